"""Tests of app/services/robots/."""
