"""A robot's tool table changes only the tools tcpcal manages, in a form each controller
merges, and says so in its header (issue 37): for every format.

The controller's own files come from public controller backups (tests/data/controller-files,
sources in tests/data/README.md): a KSS 8 $config.dat tool section with three tools of its own
and a DX100 TOOL.CND. Applying a file the way its header says to must leave every tool tcpcal
does not manage as the controller had it.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from app.vendors.files import FileContext, FileTool
from app.vendors.registry import controller_file, parse_controller_file
from tests.vendors.tools import tool_data

DATA = Path(__file__).parents[1] / "data" / "controller-files"
#: tcpcal manages tools 5 and 9 of this robot; the controller has others (1-3 in the backup).
MANAGED = (5, 9)


def managed_tools(symbols: bool = False) -> list[FileTool]:
    tools = []
    for n, slot in enumerate(MANAGED):
        symbol = f"T_ROB1/user/tTool{slot}" if symbols else None
        position = np.array([1.0 + n, -2.0, 150.0 + n])
        rotation, cog = np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.0, 0.0, 80.0])
        data = tool_data(slot, f"tcpcal tool {slot}", position, rotation, 2.5, cog)
        if symbols:
            data = replace(data, controller_symbol=symbol)
        tools.append(FileTool(data))
    return tools


def table(fmt: str, tools: list[FileTool] | None = None) -> str:
    context = FileContext("cell7", "https://tcpcal.example", table=True)
    return controller_file(fmt, tools or managed_tools(), context).text


def _lhs(line: str) -> str | None:
    """`TOOL_DATA[3]` of `TOOL_DATA[3]={...}`: what a $config.dat line initialises."""
    match = re.match(r"^\s*(\$?\w+\[[\d,\s]*\])\s*=", line)
    return match.group(1).lstrip("$").replace(" ", "") if match else None


def apply_to_config(config: str, ours: str) -> str:
    """What the header says to do: replace the lines of the same numbers in $config.dat."""
    assigned = {_lhs(line): line for line in ours.splitlines() if _lhs(line)}
    return "\n".join(assigned.get(_lhs(line), line) for line in config.splitlines()) + "\n"


def test_kuka_table_holds_only_the_managed_elements_and_merges_into_config_dat() -> None:
    text = table("kuka")
    code = [line for line in text.splitlines() if not line.startswith(";")]
    assert not any(line.startswith("DECL") for line in code), "a whole array is declared"
    targets = sorted(_lhs(line) or line for line in code)
    assert targets == [
        "LOAD_DATA[5]", "LOAD_DATA[9]", "TOOL_DATA[5]", "TOOL_DATA[9]",
        "TOOL_NAME[5,]", "TOOL_NAME[9,]",
    ]  # fmt: skip
    assert "; changes only tool(s) 5, 9:" in text
    assert "every other tool is untouched" in text
    # Applied to a real controller's tool section, the controller's own tools 1-3 stay.
    config = (DATA / "kuka_config_tools.dat").read_text()
    merged = apply_to_config(config, text)
    before = {p.slot: p for p in parse_controller_file("kuka", config)}
    after = {p.slot: p for p in parse_controller_file("kuka", merged)}
    for slot in (1, 2, 3):
        assert after[slot].name == before[slot].name == f"TOOL {slot}"
        assert after[slot].mass_kg == before[slot].mass_kg
        np.testing.assert_array_equal(after[slot].position_mm, before[slot].position_mm)
    assert after[5].name == "tcpcal tool 5"
    assert after[9].mass_kg == 2.5
    changed = [a for a, b in zip(config.splitlines(), merged.splitlines(), strict=True) if a != b]
    assert len(changed) == 6


def test_kuka_leaves_the_load_of_a_tool_whose_load_tcpcal_does_not_know() -> None:
    bare = FileTool(tool_data(4, "bare", np.array([0.0, 0.0, 90.0]), np.array([1.0, 0, 0, 0])))
    text = table("kuka", [bare])
    assert "LOAD_DATA[" not in text
    assert "; no load known for tool(s) 4: no LOAD_DATA line" in text


def test_abb_module_assigns_the_managed_tooldata_by_controller_symbol_and_declares_nothing_else(
) -> None:  # fmt: skip
    text = table("abb", managed_tools(symbols=True))
    # The tools' persistents live in module `user` (their controller_symbol): not re-declared
    # (a second declaration would keep the value in use), assigned by the module's routine.
    assert "PERS tooldata" not in text
    routine = re.search(r"^  PROC (\w+)\(\)\n(.*?)^  ENDPROC$", text, re.M | re.S)
    assert routine is not None
    assert routine.group(1) == "tcpcal_set_tools"
    assigned = re.findall(r"^    (\w+):=\[TRUE,", routine.group(2), re.M)
    assert assigned == ["tTool5", "tTool9"]
    header = " ".join(line[4:] for line in text.splitlines() if line.startswith("  ! "))
    assert "every other tool and all other data of the controller are untouched" in header
    assert "load it into task T_ROB1" in header
    assert "changes only the tooldata tTool5 (T_ROB1/user/tTool5), tTool9" in header
    assert [p.name for p in parse_controller_file("abb", text)] == ["tTool5", "tTool9"]


def test_abb_module_declares_a_tool_without_a_symbol_and_assigns_it_too() -> None:
    text = table("abb")
    assert re.findall(r"^  PERS tooldata (\w+):=", text, re.M) == ["tcpcal_tool_5", "tcpcal_tool_9"]
    assert re.findall(r"^    (\w+):=", text, re.M) == ["tcpcal_tool_5", "tcpcal_tool_9"]
    assert "tcpcal_tool_5 (declared here)" in text


def test_fanuc_program_sets_only_the_managed_frames_and_says_so() -> None:
    text = table("fanuc")
    assert sorted(re.findall(r"UTOOL\[(\d+)\]=PR\[", text)) == ["5", "9"]
    for other in ("UFRAME", "PAYLOAD", "UTOOL_NUM="):
        assert other not in text
    remarks = " ".join(re.findall(r"^ +\d+:  !(.*) ;$", text, re.M))
    assert "changes only tool frame(s) 5, 9" in remarks
    assert "every other tool frame is untouched" in remarks
    assert "PR[100] carries the numbers: its old value is lost" in remarks


def test_ur_script_defines_functions_only_and_says_what_a_call_changes() -> None:
    text = table("ur")
    code = [line for line in text.splitlines() if not line.startswith("#")]
    outside = [line for line in code if not line.startswith(("def ", "  ", "end"))]
    assert outside == [], "a statement outside a function would run when the file is loaded"
    assert "# defines tcpcal_tcpcal_tool_5(), tcpcal_tcpcal_tool_9() and changes nothing" in text
    assert "the installation's TCPs and every other tool are untouched" in text


def test_techman_lines_say_they_change_the_running_projects_tcp_only() -> None:
    text = table("techman")
    assert len(re.findall(r"^ChangeTCP\(", text, re.M)) == 2
    header = " ".join(line[3:] for line in text.splitlines() if line.startswith("// "))
    assert "sets the current TCP (and mass) of the running project" in header
    assert "the TCP list stored on the controller is untouched" in header


def test_yaskawa_blocks_merge_into_the_controllers_own_tool_file() -> None:
    """TOOL.CND has no comments and loads as a whole file: the blocks merge into the
    controller's saved TOOL.CND, every other block byte for byte as it was."""
    from app.vendors.yaskawa.file import merge  # here: the other tests run without it

    saved = (DATA / "yaskawa_TOOL.CND").read_text()
    ours = controller_file(
        "yaskawa", [FileTool(tool_data(3, "tcpcal torch", np.array([1.0, 2.0, 3.0]),
                                      np.array([1.0, 0, 0, 0]), 2.5, np.array([0, 0, 80.0])))]
    ).text  # fmt: skip
    merged = merge(saved, ours)
    blocks = {p.slot: p for p in parse_controller_file("yaskawa", merged)}
    assert list(blocks) == [0, 1, 2, 3, 4]
    assert blocks[3].name == "tcpcal torch"
    assert blocks[3].mass_kg == 2.5
    kept = saved.split("//TOOL 3\n")[0]
    assert merged.startswith(kept)  # tools 0-2 byte for byte
    assert merged.endswith(saved[saved.index("//TOOL 4\n") :])  # and tool 4
    # a number the saved file lacks is refused, naming it, not appended
    with pytest.raises(Exception, match=r"no block for tool\(s\) \[5, 9\]"):
        merge(saved, table("yaskawa"))


def test_yaskawa_merge_into_a_yrc1000_file_keeps_its_crc_lines() -> None:
    """A YRC1000 TOOL.CND has a ///CRC line in every block (the same value in each): the
    merged block keeps the controller's line, every other block stays as it was."""
    from app.vendors.yaskawa.file import merge

    saved = (DATA / "yaskawa_TOOL_yrc1000.CND").read_text()
    tool = tool_data(3, "tcpcal suction", np.array([1.0, 2.0, 3.0]), np.array([1.0, 0, 0, 0]))
    merged = merge(saved, controller_file("yaskawa", [FileTool(tool)]).text)
    block = merged[merged.index("//TOOL 3\n") : merged.index("//TOOL 4\n")]
    assert block.splitlines()[:3] == ["//TOOL 3", "///CRC 3243358777", "///NAME tcpcal suction"]
    assert merged.startswith(saved[: saved.index("//TOOL 3\n")])
    assert merged.endswith(saved[saved.index("//TOOL 4\n") :])
    assert [t.name for t in parse_controller_file("yaskawa", merged)] == [
        "POINTER TCP", "tcpcal suction", "SUCTION2",
    ]  # fmt: skip
