"""Drivers for real rigs: turntables, climatic chambers and IMU streams."""
