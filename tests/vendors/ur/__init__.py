"""Universal Robots' connector (RTDE) against the UR simulator."""
