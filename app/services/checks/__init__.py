"""Checks of a tool's active TCP against a reference point (checks) and the re-check after a
collision that may correct and deploy it (recheck), one function for HTTP
(app/api/checks.py), the CLI and MQTT.
"""
