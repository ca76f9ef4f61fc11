"""JSON documents as Python holds them: the one boundary where an untyped value is honest.

Used for what is kept exactly as JSON (a submission as received, a JSON column, an audit
record's details, a controller's values); everything the code computes has a model.
"""

from __future__ import annotations

from typing import Any

JsonObject = dict[str, Any]
JsonArray = list[Any]
