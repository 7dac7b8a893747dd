"""The Streamlit lab dashboard: ``app.py`` discovers ``dashboard/pages/NN_name.py``; ``common`` holds the shared helpers."""
