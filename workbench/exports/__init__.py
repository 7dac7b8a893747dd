"""Export formats of calibration sets, one module per format (see workbench.registry)."""
