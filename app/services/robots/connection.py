"""A robot's controller connection: set, read, remove; the password encrypted at rest."""

from __future__ import annotations

import ipaddress
import re
from typing import NamedTuple

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from app.errors import (
    ConnectorMissing,
    InvalidInput,
    NoController,
    NoControllerSet,
    SecretUnreadable,
)
from app.schemas.controllers import ControllerIn
from app.security import secretbox
from app.security.auth import Principal
from app.services.audit import writes as audit
from app.services.robots import live_tool
from app.services.robots.live_frame import forget_live_frame
from app.services.robots.robots import get_robot
from app.storage.models import Robot, RobotController, Tool, controller_state_models, utcnow
from app.vendors.connector import (
    ControllerCredentialsRefused,
    ControllerRefused,
    ControllerSettings,
)
from app.vendors.registry import (
    DEFAULT_PORTS,
    SERVICE_PORTS,
    SLOT_RANGES,
    has_connector,
    pose_format_of,
    scope_of,
    vendor_protocols,
    vendor_speaks,
)
from app.words import ProtocolName


def get_controller(
    session: Session, robot_id: str, *, missing: type[NoController | NoControllerSet] = NoController
) -> RobotController:
    """The controller connection of a live robot; 404 for the robot; `missing` when it has
    none: 409 /no-controller for what needs one (deploy, reconcile), 404 /no-controller for
    reading the connection itself (contract v1.3)."""
    get_robot(session, robot_id)
    controller = session.get(RobotController, robot_id)
    if controller is None:
        raise missing(
            f"robot {robot_id} has no controller: PUT /v1/robots/{robot_id}/controller first"
        )
    return controller


def refusal_words(exc: ControllerRefused, robot_id: str) -> str:
    """The controller's own words and, when known, what to do about them."""
    remedy = exc.remedy
    if isinstance(exc, ControllerCredentialsRefused):
        remedy = (
            f"it refused user {exc.user!r} with the password tcpcal holds: set the user and "
            f"password it accepts as `username` and `password` with PUT "
            f"/v1/robots/{robot_id}/controller"
        )
    return exc.controller_message if remedy is None else f"{exc.controller_message}; {remedy}"


_LABEL = re.compile(r"^(?!-)[A-Za-z0-9-]{1,63}(?<!-)$")


def check_host(host: str) -> None:
    """A host name (RFC 1123 labels) or an IPv4/IPv6 address, as a controller is reached, else
    422 /invalid-host on body.host. Checked here rather than in the request schema, whose
    pattern language could not say it without admitting strings that are neither."""
    try:
        ipaddress.ip_address(host)
        return
    except ValueError:
        pass
    labels = host.rstrip(".").split(".")
    if not all(_LABEL.match(label) for label in labels):
        raise InvalidInput(
            "invalid-host",
            f"host {host!r} is neither a host name (letters, digits and -, in dot-separated "
            "labels of at most 63) nor an IPv4/IPv6 address: give the controller's address "
            "as its network settings show it",
            loc=("body", "host"),
        )


def _services_text(protocol: ProtocolName) -> str:
    return ", ".join(f"{name} (default {port})" for name, port in SERVICE_PORTS[protocol].items())


def ports_in_use(data: ControllerIn) -> tuple[int | None, dict[str, int] | None]:
    """(`port`, `ports`) as stored: a single-service protocol's port, or every service's
    port of a protocol of several, defaults filled in; 422 naming the field for `port` sent
    to a protocol of several services, `ports` to one of one, or a service it does not have
    (contract v1.3: such a protocol takes `ports` in place of `port`)."""
    protocol = data.protocol
    if protocol not in SERVICE_PORTS:
        if data.ports is not None:
            raise InvalidInput(
                "validation",
                f"{protocol} is reached on one port: give it as `port` (default "
                f"{DEFAULT_PORTS[protocol]}), not `ports`, which only a protocol of several "
                f"services takes ({', '.join(SERVICE_PORTS)})",
                loc=("body", "ports"),
            )
        return (data.port if data.port is not None else DEFAULT_PORTS[protocol]), None
    if data.port is not None:
        raise InvalidInput(
            "validation",
            f"{protocol} is reached on several ports, one a service: give them as `ports` "
            f"(services {_services_text(protocol)}; any left out keeps its default), not `port`",
            loc=("body", "port"),
        )
    given = data.ports or {}
    for service in given:
        if service not in SERVICE_PORTS[protocol]:
            raise InvalidInput(
                "validation",
                f"{protocol} has no service {service!r}: its services are "
                f"{_services_text(protocol)}; name the port by one of them",
                loc=("body", "ports", service),
            )
    return None, {name: given.get(name, port) for name, port in SERVICE_PORTS[protocol].items()}


def put_controller(
    session: Session, *, robot_id: str, data: ControllerIn, fields_sent: set[str], actor: Principal
) -> RobotController:
    """Set how to reach the robot's controller. A password left out keeps the stored one;
    null removes it. Its live tools must be addressable under the protocol (422 otherwise)."""
    robot = get_robot(session, robot_id, for_update=True)
    check_host(data.host)
    controller = session.get(RobotController, robot_id)
    _protocol_of_vendor(robot, data.protocol, has_controller=controller is not None)
    port, ports = ports_in_use(data)
    _tools_addressable(session, robot_id, data.protocol)
    created = controller is None
    if controller is None:
        controller = RobotController(robot_id=robot_id, created_at=utcnow())
        session.add(controller)
    if "password" in fields_sent:
        controller.password_encrypted = _encrypted(data)
    controller.protocol = data.protocol
    controller.host = data.host
    controller.port = port
    controller.ports = ports
    controller.username = data.username
    controller.timeout_s = data.timeout_s
    controller.tls_verify = data.tls_verify
    controller.updated_at = utcnow()
    session.flush()
    audit.record(
        session,
        actor=actor,
        action="controller.set",
        resource_type="robot",
        resource_id=robot_id,
        robot_id=robot_id,
        details={
            "created": created,
            "protocol": controller.protocol,
            "host": controller.host,
            "port": controller.port,
            "ports": controller.ports,
            "password_changed": "password" in fields_sent,  # never the password itself
        },
    )
    return controller


def _protocol_of_vendor(robot: Robot, protocol: ProtocolName, *, has_controller: bool) -> None:
    """422 naming body.protocol when the robot's vendor is a maker whose controllers do not
    speak `protocol` (a robot of one maker given another's protocol): every capture would
    then talk another maker's protocol to it. A vendor no maker is known by takes any protocol.
    The advice for a wrong vendor: correct it; with a controller already set (whose protocol
    the other maker's controllers do not speak, so the vendor's PATCH is refused), remove the
    controller first."""
    if vendor_speaks(robot.vendor, protocol):
        return
    fitting = vendor_protocols(robot.vendor)
    correct = f"correct the robot's vendor (PATCH /v1/robots/{robot.id})"
    if has_controller:
        correct = (
            f"remove its controller first (DELETE /v1/robots/{robot.id}/controller, or "
            f"tcpcal disconnect {robot.name}), then {correct} and connect it again"
        )
    raise InvalidInput(
        "validation",
        f"protocol {protocol} is not its robot's: robot {robot.name}'s vendor is "
        f"{robot.vendor!r}, and its controllers speak {', '.join(fitting)}: give one of those, "
        f"or, if the vendor is wrong, {correct}; nothing was stored",
        loc=("body", "protocol"),
        context={"vendor": robot.vendor, "protocols": list(fitting)},
    )


def _encrypted(data: ControllerIn) -> str | None:
    if data.password is None:
        return None
    if not secretbox.key_configured():
        raise InvalidInput(
            "missing-secret-key",
            f"a controller password is stored encrypted, and {secretbox.SECRET_ENV} is not "
            f"set: set {secretbox.SECRET_ENV} (a long random string, the same on every "
            "instance) and send it again; nothing was stored",
            loc=("body", "password"),
        )
    return secretbox.encrypt(data.password.get_secret_value())


def _tools_addressable(session: Session, robot_id: str, protocol: ProtocolName) -> None:
    """422 naming the first live tool whose slot is outside the protocol's tool numbers (a
    tool without its slot or symbol is refused when it is deployed: it may be set later)."""
    if protocol not in SLOT_RANGES:
        return
    low, high = SLOT_RANGES[protocol]
    outside = session.execute(
        select(Tool.id, Tool.name, Tool.slot).where(
            Tool.robot_id == robot_id,
            Tool.archived_at.is_(None),
            Tool.slot.is_not(None),
            (Tool.slot < low) | (Tool.slot > high),
        )
    ).first()
    if outside is not None:
        raise InvalidInput(
            "controller-target",
            f"tool {outside.name!r} ({outside.id}) has slot {outside.slot}, outside {low}-{high}, "
            f"the tool numbers of a {protocol} controller: change its slot first",
            loc=("body", "protocol"),
        )


def check_slot_for_controller(session: Session, *, robot_id: str, slot: int | None) -> None:
    """422 naming `slot` when the robot's controller numbers its tools and `slot` is not
    one of its numbers (its maker's tool numbers, registry.SLOT_RANGES)."""
    if slot is None:
        return
    protocol = session.scalar(
        select(RobotController.protocol).where(RobotController.robot_id == robot_id)
    )
    if protocol is None or protocol not in SLOT_RANGES:
        return
    low, high = SLOT_RANGES[protocol]
    if not low <= slot <= high:
        raise InvalidInput(
            "controller-target",
            f"slot {slot} is outside {low}-{high}, the tool numbers of this robot's "
            f"{protocol} controller: choose a slot in {low}-{high}",
            loc=("body", "slot"),
        )


def delete_controller(session: Session, *, robot_id: str, actor: Principal) -> None:
    """Forget how to reach the robot's controller and what it was found holding of each
    subject (tools, frames; their deployments stay in the history)."""
    controller = get_controller(session, robot_id)
    session.delete(controller)
    # Without a controller nothing is known of what it holds: the fleet stops saying so.
    for state in controller_state_models():
        session.execute(delete(state).where(state.robot_id == robot_id))
    live_tool.forget_live(session, robot_id)
    forget_live_frame(session, robot_id)
    audit.record(
        session,
        actor=actor,
        action="controller.delete",
        resource_type="robot",
        resource_id=robot_id,
        robot_id=robot_id,
    )


def controller_document(controller: RobotController) -> dict[str, object]:
    """The controller as served: the password only as `has_password`."""
    return {
        "robot_id": controller.robot_id,
        "protocol": controller.protocol,
        "host": controller.host,
        "port": controller.port,
        "ports": controller.ports,
        "username": controller.username,
        "scope": scope_of(controller.protocol),
        "has_password": controller.password_encrypted is not None,
        "pose_format": pose_format_of(controller.protocol),
        "timeout_s": controller.timeout_s,
        "tls_verify": controller.tls_verify,
        "created_at": controller.created_at,
        "updated_at": controller.updated_at,
    }


class StoredController(NamedTuple):
    """A robot's stored controller, the columns settings_of reads (a round reads them on
    the driver's cursor: app.services.controllers.reconcile)."""

    robot_id: str
    protocol: ProtocolName
    host: str
    port: int | None
    ports: dict[str, int] | None
    username: str | None
    password_encrypted: str | None
    timeout_s: float
    tls_verify: bool


def settings_of(controller: RobotController | StoredController) -> ControllerSettings:
    """What a connector needs, the password decrypted (in memory only); 409 when the
    secret key cannot open it, 501 when this tcpcal has no connector for its protocol."""
    if not has_connector(controller.protocol):
        raise ConnectorMissing(
            f"this tcpcal has no {controller.protocol} connector yet: the connection to "
            f"robot {controller.robot_id}'s controller is stored, and deploying, reconciling "
            "and capturing work once a tcpcal with the connector serves it; nothing was "
            "sent to the controller"
        )
    password = None
    if controller.password_encrypted is not None:
        try:
            password = secretbox.decrypt(controller.password_encrypted)
        except secretbox.SecretUnavailable as exc:
            raise SecretUnreadable(str(exc)) from None
    ports = dict(controller.ports or {})
    port = controller.port
    if port is None:  # a protocol of several services: its main (first) service's port
        main, default = next(iter(SERVICE_PORTS[controller.protocol].items()))
        port = ports.get(main, default)
    return ControllerSettings(
        protocol=controller.protocol,
        host=controller.host,
        port=port,
        username=controller.username,
        password=password,
        timeout_s=controller.timeout_s,
        tls_verify=controller.tls_verify,
        ports=ports,
    )
