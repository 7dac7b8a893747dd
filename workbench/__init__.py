"""Calibration workbench for inertial and magnetic sensors."""

__version__ = "0.1.0"
