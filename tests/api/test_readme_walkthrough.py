"""Replays the README's first-session walkthrough and checks the values it shows.

The shell blocks between the walkthrough markers are parsed (curl calls, `VAR=$(... | jq -r
.field)` captures, `| jq .field` filters) and sent through the in-process client; each JSON
block after a call must be contained in that call's answer.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path
from typing import Any

from tests.conftest import Api

README = Path(__file__).resolve().parents[2] / "README.md"


def _blocks() -> list[tuple[str, str]]:
    text = README.read_text()
    section = text.split("<!-- walkthrough:start -->")[1].split("<!-- walkthrough:end -->")[0]
    return re.findall(r"```(sh|json)\n(.*?)```", section, flags=re.S)


def _commands(block: str) -> list[str]:
    return [c.strip() for c in block.replace("\\\n", " ").splitlines() if c.strip()]


def _contains(actual: Any, expected: Any) -> None:
    if isinstance(expected, dict):
        assert isinstance(actual, dict), actual
        for key, value in expected.items():
            assert key in actual, f"{key} missing in {actual}"
            _contains(actual[key], value)
    else:
        assert actual == expected, f"{actual!r} != {expected!r}"


def _curl(api: Api, args: list[str]) -> Any:
    method, headers, data, url = "GET", {}, None, None
    it = iter(args[1:])
    for arg in it:
        if arg == "-X":
            method = next(it)
        elif arg == "-H":
            name, _, value = next(it).partition(":")
            headers[name.strip()] = value.strip()
        elif arg == "-d":
            data = next(it)
        elif arg.startswith("http"):
            url = arg
        else:
            assert arg in {"-s", "-i"}, f"unexpected curl argument {arg}"
    assert url is not None
    path = url.removeprefix("http://127.0.0.1:8000")
    response = api.client.request(method, path, headers=headers, content=data)
    assert response.status_code < 400, response.text
    return response.json()


def test_readme_walkthrough(api: Api) -> None:
    env = {"URL": "http://127.0.0.1:8000", "KEY": api.keys["admin"]}
    last: Any = None
    calls = 0
    for kind, block in _blocks():
        if kind == "json":
            _contains(last, json.loads(block))
            continue
        for command in _commands(block):
            command = command.removeprefix("export ")
            target = None
            capture = re.fullmatch(r"(\w+)=\$\((.*)\)", command, flags=re.S)
            if capture:
                target, command = capture.group(1), capture.group(2).strip()
            if not command.startswith("curl"):
                # URL= and KEY=$(tcpcal keys create ...): the test uses its own admin key
                assert re.match(r"(URL|KEY)=", command) or target == "KEY", command
                continue
            pipeline = [p.strip() for p in command.split(" | ")]
            words = shlex.split(re.sub(r"\$(\w+)", lambda m: env[m.group(1)], pipeline[0]))
            result = _curl(api, words)
            calls += 1
            for stage in pipeline[1:]:
                field = re.fullmatch(r"jq (?:-r )?\.(\w+)", stage)
                assert field, stage
                result = result[field.group(1)]
            if target:
                env[target] = result
            last = result
    assert calls >= 6
