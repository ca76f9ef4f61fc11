"""Pure calibration mathematics over numpy arrays: no web, no database, no pydantic."""
