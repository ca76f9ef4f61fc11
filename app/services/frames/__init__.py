"""A robot's frames (contract v1.4 "Frames"): bases and fixed tools (frames), their versions,
activation and the active frame served (versions over app.services.lifecycle, with the
frame's declaration: subject), each the one lifecycle's, never a copy of the tool's.
"""
