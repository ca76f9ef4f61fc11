"""Seeded simulators of calibration measurements with known truth."""
