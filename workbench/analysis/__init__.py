"""Pure estimators: each takes arrays or a Session and returns a result object with uncertainties."""
