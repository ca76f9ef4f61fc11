"""Tests of app/services/calibrations/."""
