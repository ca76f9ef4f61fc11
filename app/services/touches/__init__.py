"""What every feature that reads touches shares: the frame they are read in (the tool's
active TCP, poses parsed in a controller's format: tool_frames) and the unit and convention
mix-ups refused in them (diagnosis). Used by calibrations, sessions, checks and references.
"""
