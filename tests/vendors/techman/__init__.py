"""Techman's connector (TMflow) against the TMflow simulator."""
