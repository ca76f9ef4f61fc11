"""Tests of app/services/tools/."""
