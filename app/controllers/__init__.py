"""Controller connectors: write a tool frame into a robot controller and read it back.

One module per wire protocol behind one `Connector` interface (app.controllers.base):

| protocol | module | vendor document followed |
|---|---|---|
| kuka_kvp | kuka_kvp.py | KUKAVARPROXY / OpenShowVar (ImtsSrl/KUKAVARPROXY README) |
| fanuc_rmi | fanuc_rmi.py | FANUC B-84184EN Remote Motion Interface Operator's Manual |
| abb_rws1 | abb_rws.py | ABB Robot Web Services 1.0 (RobotWare 6) |
| abb_rws2 | abb_rws.py | ABB Robot Web Services 2.0 (RobotWare 7) |

`connect(settings)` opens a session with the connector its protocol names. Beside them:
`krl.py` (KRL structure texts) and `rapid.py` (RAPID tooldata texts), both read with
`scanner.py`, and `sockets.py` (TCP I/O under one deadline). Each read or write has its own
deadline of ``timeout_s`` covering all its network waits; a session whose controller
stopped answering closes without waiting again. The simulators the tests drive are in
tests/controllers/.
"""

from __future__ import annotations

from app.controllers.base import (
    DEFAULT_PORTS,
    PROTOCOLS,
    SERVICE_PORTS,
    SLOT_RANGES,
    TARGET_FIELD,
    Connector,
    ControllerError,
    ControllerProtocolError,
    ControllerRefused,
    ControllerSettings,
    ControllerUnreachable,
    ProtocolName,
    ToolData,
    ToolLoad,
    ToolTarget,
    abb_symbol_problem,
    check_target,
    describe_target,
    split_abb_symbol,
    target_problem,
)

__all__ = [
    "CONNECTED_PROTOCOLS",
    "DEFAULT_PORTS",
    "PROTOCOLS",
    "SERVICE_PORTS",
    "SLOT_RANGES",
    "TARGET_FIELD",
    "Connector",
    "ControllerError",
    "ControllerProtocolError",
    "ControllerRefused",
    "ControllerSettings",
    "ControllerUnreachable",
    "ProtocolName",
    "ToolData",
    "ToolLoad",
    "ToolTarget",
    "abb_symbol_problem",
    "check_target",
    "connect",
    "describe_target",
    "has_connector",
    "split_abb_symbol",
    "target_problem",
]


#: The protocols `connect` has a connector for (a protocol's connector adds it here). A
#: controller of another protocol in PROTOCOLS is stored, and nothing is sent to it
#: (app.services.controllers.settings_of answers 501 /no-connector).
CONNECTED_PROTOCOLS: frozenset[str] = frozenset({"kuka_kvp", "fanuc_rmi", "abb_rws1", "abb_rws2"})


def has_connector(protocol: str) -> bool:
    """Whether `connect` can open a session under `protocol`."""
    return protocol in CONNECTED_PROTOCOLS


def connect(settings: ControllerSettings) -> Connector:
    """Open a session with the controller `settings` describes, by its protocol.

    Raises ControllerUnreachable when it cannot be reached within ``settings.timeout_s``,
    ControllerRefused when it refuses the session (credentials), ValueError for a protocol
    it has no connector for (`has_connector`), naming it.
    """
    # Imported here so that importing the package (the data, the errors) loads no client.
    if settings.protocol == "kuka_kvp":
        from app.controllers.kuka_kvp import KukaKvpConnector

        return KukaKvpConnector(settings)
    if settings.protocol == "fanuc_rmi":
        from app.controllers.fanuc_rmi import FanucRmiConnector

        return FanucRmiConnector(settings)
    if settings.protocol in ("abb_rws1", "abb_rws2"):
        from app.controllers.abb_rws import AbbRwsConnector

        return AbbRwsConnector(settings)
    if settings.protocol in PROTOCOLS:
        raise ValueError(
            f"no connector for controller protocol {settings.protocol!r} in this tcpcal yet; "
            f"connected: {', '.join(sorted(CONNECTED_PROTOCOLS))}"
        )
    raise ValueError(f"unknown controller protocol {settings.protocol!r}; known: {PROTOCOLS}")
