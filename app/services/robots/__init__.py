"""A robot and what is set on it: the robot (robots), the tool numbers its controller has
(slots), its controller connection (connection), and which TCP it moves by, as its
controller last reported (live_tool).
"""
