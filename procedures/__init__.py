"""Lab procedures: one module per procedure (a sequence plus its analysis)."""
