"""Yaskawa's connector (HSES) against the HSES simulator."""
