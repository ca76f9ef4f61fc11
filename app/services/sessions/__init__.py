"""Guided calibration sessions (app/api/sessions.py): a plan, touches typed or captured one at a
time with the next one suggested, and the finish that submits them as a calibration (sessions).
"""
