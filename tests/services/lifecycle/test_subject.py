"""Every declared subject is of the shape the one lifecycle reads (app.services.lifecycle), and
the lifecycle never names a subject: what differs between subjects is in their declarations."""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import get_args

import pytest

from app.services import subjects
from app.services.lifecycle.subject import AnySubject
from app.storage.models import SUBJECT_KEYS, AuditEvent, OutboxMessage, table_of
from app.words import ResourceType

LIFECYCLE = Path(__file__).resolve().parents[3] / "app" / "services" / "lifecycle"

SUBJECT_COLUMNS = {
    "id", "robot_id", "name", "tolerance", "active_version", "last_version", "revision",
    "updated_at", "archived_at", "drift", "drift_crosses_at", "slot", "controller_symbol",
}  # fmt: skip
VERSION_COLUMNS = {
    "version", "position_mm", "quaternion", "source", "status", "calibration_id", "note",
    "created_at", "created_by",
}  # fmt: skip
ACTIVATION_COLUMNS = {
    "id", "version", "previous_version", "reason", "reason_text", "activated_at",
    "activated_by",
}  # fmt: skip
DEPLOYMENT_COLUMNS = {
    "id", "robot_id", "version", "protocol", "target", "status", "scope", "previous",
    "read_back", "deviation_mm", "deviation_deg", "error", "reason", "settled", "actor",
    "created_at",
}  # fmt: skip
STATE_COLUMNS = {
    "robot_id", "state", "since", "checked_at", "target", "deviation_mm", "deviation_deg",
    "controller", "active_version", "error",
}  # fmt: skip
DEPLOYED = [s for s in subjects.SUBJECTS if s.controller is not None]


@pytest.mark.parametrize("subject", subjects.SUBJECTS, ids=lambda s: s.kind)
def test_each_subjects_tables_have_the_lifecycles_columns(subject: AnySubject) -> None:
    assert SUBJECT_COLUMNS - set(subject.table.c.keys()) == set()
    assert (VERSION_COLUMNS | {subject.key}) - set(subject.versions.c.keys()) == set()
    assert (ACTIVATION_COLUMNS | {subject.key}) - set(subject.activations.c.keys()) == set()
    assert {"id", "result"} - set(subject.calibrations.c.keys()) == set()
    if subject.served_detail is not None:  # a JSON column of the subject's own
        assert subject.served_detail in subject.table.c
    # The key names the subject in the audit trail and the outbox as well.
    assert subject.key in table_of(AuditEvent).c
    assert subject.key in table_of(OutboxMessage).c


@pytest.mark.parametrize("subject", DEPLOYED, ids=lambda s: s.kind)
def test_each_deployed_subjects_controller_tables_have_the_columns_read(
    subject: AnySubject,
) -> None:
    """A subject deployed to controllers declares its deployments' and its controller
    states' tables, each of the one shape app.services.controllers reads, and names the
    subject in each by its key (the state's primary key)."""
    assert subject.deployments is not None
    assert subject.states is not None
    assert (DEPLOYMENT_COLUMNS | {subject.key}) - set(subject.deployments.c.keys()) == set()
    assert (STATE_COLUMNS | {subject.key}) - set(subject.states.c.keys()) == set()
    assert [c.name for c in subject.states.primary_key] == [subject.key]
    assert subject.deployments.c[subject.key].references(subject.table.c.id)
    assert subject.states.c[subject.key].references(subject.table.c.id)


def test_the_tool_is_deployed() -> None:
    assert [s.kind for s in DEPLOYED][:1] == ["tool"]


def test_the_subjects_are_one_each_by_kind_and_key() -> None:
    kinds = [s.kind for s in subjects.SUBJECTS]
    assert len(set(kinds)) == len(kinds)
    assert set(kinds) <= set(get_args(ResourceType))
    assert tuple(s.key for s in subjects.SUBJECTS) == SUBJECT_KEYS
    assert {s.kind: s for s in subjects.SUBJECTS} == subjects.BY_KIND


def _code_words(path: Path) -> list[str]:
    """The names, attributes and string constants of a module's code (docstrings aside)."""
    tree = ast.parse(path.read_text())
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    words = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            words.append(node.id)
        elif isinstance(node, ast.Attribute):
            words.append(node.attr)
        elif (
            isinstance(node, ast.Constant)
            and isinstance(node.value, str)
            and id(node) not in docstrings
        ):
            words.append(node.value)
    return words


@pytest.mark.parametrize("path", sorted(LIFECYCLE.glob("*.py")), ids=lambda p: p.name)
def test_the_lifecycle_names_no_subject(path: Path) -> None:
    """A word of a subject in the lifecycle's code (a tool_id column, a "TCP" in a message)
    would make it the tool's lifecycle again: each must come from the declaration."""
    named = [
        word
        for word in _code_words(path)
        if {"tool", "tools", "tcp"} & set(re.split(r"[^a-z]+", word.lower()))
    ]
    assert named == []
