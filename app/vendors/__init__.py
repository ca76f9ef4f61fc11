"""The controller makers: one package each, and what they share.

| module | what |
|---|---|
| registry.py | the makers, and what the rest of tcpcal asks of them (by format, vendor, protocol) |
| maker.py | what a maker's package declares (`Maker`, `WireProtocol`) |
| tool.py | `ToolData` and `ToolLoad`: a tool as a controller holds it |
| frame.py | `FrameData`, `FileFrame`, `ParsedFrame`: a frame (a base, a fixed tool) likewise |
| connector.py | the connector (tools, frames): `Connector`, settings, errors, `Deadline` |
| text.py | a maker's text: `ControllerExport`, the checked TCP, printing and reading numbers |
| files.py | a maker's file: `ControllerFile`, `FileContext`, `FileTool`, `ParsedTool`, headers |
| names.py | tool names made safe for a controller (ASCII, identifiers, file stems) |
| wpr.py | X Y Z and fixed-axis angles (Rz Ry Rx): fanuc_wpr, yaskawa_rxyz, techman_rxyz |
| scanner.py | a cursor over a controller's value text (KRL, RAPID) |
| sockets.py | blocking TCP I/O under one deadline (the makers' socket protocols) |
| <maker>/ (registry.MAKERS) | one maker each: text.py, file.py, frame.py, connector |

No web framework, database or pydantic here (import contracts in pyproject.toml), and no
maker imports another. Importing the package imports nothing.
"""
