"""A tool and its TCP: the tool (tools), its versions numbered, activated and rolled back
(versions, activation), its drift trend (drift), and the active TCP served as JSON or
in its controller's syntax (active_tcp over hot_read; controller_text, controller_files).
"""
