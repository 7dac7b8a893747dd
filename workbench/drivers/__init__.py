"""Drivers for real rigs: turntables, climatic chambers and IMU streams (see ``docs/rigs.md``).

``transport`` (serial/TCP line links), ``turntable_visa`` (PyVISA), ``chamber_ascii`` and
``chamber_modbus``, ``imu_stream`` (frames to SI), ``rig`` (:class:`RealRig`,
:func:`open_real_rig`), ``hil`` (the loopback hardware-in-the-loop simulator).
"""
