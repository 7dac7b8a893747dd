"""Navigation filters that consume calibration sets: compensation, AHRS, ZUPT alignment."""
