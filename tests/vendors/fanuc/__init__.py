"""FANUC's connector (RMI) against the RMI simulator; the LS grammar."""
