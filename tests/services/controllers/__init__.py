"""Tests of app/services/controllers/."""
