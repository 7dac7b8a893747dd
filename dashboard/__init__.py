"""The Streamlit lab dashboard: ``app.py`` discovers ``dashboard/pages/NN_name.py``.

Shared helpers, one job per module: ``ui`` (store, errors, lab units, links), ``forms`` (grades,
procedures, options, sequences), ``jobs`` (background runs read back from their files),
``results`` (sessions and stored results), ``charts`` (sample plots), ``roots`` (readable folders).
"""
