"""ABB's connector (RWS 1.0 and 2.0) against the RWS simulator."""
