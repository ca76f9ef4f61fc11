"""What a calibration, and the TCP version it writes, is stored as: within the tool's
tolerance or not (app.helpers.tolerance decides which).

Pure Python, so that the stored rows (app.models) and the documents (app.schemas) share the
one list without importing each other.
"""

from __future__ import annotations

from typing import Literal

Status = Literal["accepted", "out_of_tolerance"]
