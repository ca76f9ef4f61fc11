"""The calibrated subjects tcpcal serves, each declared in its package as one
`Subject` (app.services.lifecycle.subject), listed here as app.vendors.registry lists the
makers: what the lifecycle serves for every subject alike (the publisher's topics, the
fleet) reads this list. tests/services/lifecycle/test_subject.py holds that each declared
subject's tables are of the shape the lifecycle reads.

Adding a subject: its package (models, schemas, methods, routes) declaring its `Subject`,
its line here, its key in app.storage.models.SUBJECT_KEYS (a column of audit_events and
outbox, by a migration) and its resource type in app.words.ResourceType.
"""

from __future__ import annotations

from app.services.lifecycle.subject import AnySubject
from app.services.tools.subject import TOOL

#: Every calibrated subject, tools first.
SUBJECTS: tuple[AnySubject, ...] = (TOOL,)
#: The subjects by kind (their audit resource type).
BY_KIND: dict[str, AnySubject] = {subject.kind: subject for subject in SUBJECTS}
