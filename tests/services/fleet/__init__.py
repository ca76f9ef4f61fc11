"""Tests of app/services/fleet/."""
