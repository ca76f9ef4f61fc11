"""tcpcal: Tool Center Point calibration as a fleet service."""

__version__ = "0.1.0"
