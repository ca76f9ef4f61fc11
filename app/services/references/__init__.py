"""A robot's reference points (references) and crossed-beam laser devices (laser_devices):
entered as numbers or touched and swept by a tool whose active TCP is trusted
(app/api/references.py).
"""
