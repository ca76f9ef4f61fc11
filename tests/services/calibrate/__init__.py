"""Tests of app/services/calibrate/."""
