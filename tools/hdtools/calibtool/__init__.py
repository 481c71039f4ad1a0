"""Calibration of the built-in torque sensor: CSV in, report/record/plot out.

The analysis and the record encoding are the C library calib/ (libhdcalib.so)
loaded through ctypes; this package only parses, formats and plots.
"""
