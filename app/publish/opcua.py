"""The plant's OPC UA server: each live subject's active version (a tool's TCP, a frame) as
read-only variables.

Address space (API.md v1.2, "Publishing to the plant"), namespace URI `urn:tcpcal`:
`Objects/Robots/<robot name>/<folder>/<name>/`, a folder per subject of a robot
(app.services.subjects: `Subject.folder`, "Tools", "Frames"), with the variables
`ActiveVersion` (Int32, 0: no active version), `PositionMm` (Double[3], mm), `Quaternion`
(Double[4], w x y z), `KukaABC` (Double[3], deg), and (API.md v1.3) `Status`, `ActivationKind` and
`ActivationReason` (String: the active version's status and how it went live),
`ControllerState` (String) and `UpdatedAt` (DateTime); the arrays are empty and the strings
of the activation empty while it has no active version. Every variable has a
Description; those with a unit are BaseAnalogType with an EngineeringUnits property (Part 8,
UNECE codes); their descriptions are said in the subject's words. Node ids are stable
strings made of the robot's and the subject's ids ("tools/<id>/PositionMm"), so a client that
stored one keeps reading the same tool when it is renamed (its browse name changes).

Built on asyncua (https://github.com/FreeOpcUa/opcua-asyncio), following OPC UA Part 3
(address space: Folders, Variables with ValueRank 1 and ArrayDimensions for fixed-length
arrays, https://reference.opcfoundation.org/Core/Part3/v105/docs/) and Part 4's
ActivateSession (https://reference.opcfoundation.org/Core/Part4/v105/docs/5.6.3): a
UserNameIdentityToken is checked as user name = the API key's name, password = the key,
which must have scope `read` or above; an AnonymousIdentityToken is accepted only when
anonymous access is switched on. Clients get asyncua's `User` role: they may browse, read
and subscribe, and every Write, AddNodes or DeleteNodes is refused (BadUserAccessDenied /
BadNotWritable): the database is the one source of these values.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC
from typing import TYPE_CHECKING

from asyncua import ua
from asyncua.common.manage_nodes import delete_nodes
from asyncua.common.node import Node
from asyncua.crypto.permission_rules import User, UserRole
from asyncua.server.server import Server
from asyncua.server.user_managers import UserManager
from asyncua.ua.attribute_ids import AttributeIds
from asyncua.ua.object_ids import ObjectIds

from app.publish.endpoint import DEFAULT_PORT as DEFAULT_PORT
from app.publish.endpoint import Endpoint as Endpoint
from app.publish.endpoint import OpcUaStartError as OpcUaStartError
from app.publish.endpoint import parse_endpoint as parse_endpoint
from app.publish.opcua_certs import APPLICATION_URI, ServerCertificate
from app.services.fleet.plant import PlantItem, PlantRobot
from app.services.subjects import IN_FLEET, Served

if TYPE_CHECKING:
    from asyncua.server.internal_server import InternalServer

log = logging.getLogger(__name__)
# asyncua logs every node of the standard address space it loads, and every session, at
# INFO: thousands of lines per start. Its warnings and errors still come through.
logging.getLogger("asyncua").setLevel(logging.WARNING)

NAMESPACE_URI = "urn:tcpcal"

#: Checks an API key given as (user name, password); True when it may read.
KeyCheck = Callable[[str, str], bool]


class ApiKeyUsers(UserManager):
    """Signs clients in with an API key (user name: the key's name, password: the key)."""

    def __init__(self, check: KeyCheck, *, anonymous: bool) -> None:
        self._check = check
        self._anonymous = anonymous

    def get_user(
        self,
        iserver: InternalServer,  # unused
        username: str | None = None,
        password: str | None = None,
        certificate: object = None,  # unused: keys sign in, not certificates
    ) -> User | None:
        """A read-only user for a good key (or anonymous when allowed), None to refuse."""
        if username is None and password is None:
            return User(role=UserRole.User, name="anonymous") if self._anonymous else None
        if not username or not password or not self._check(username, password):
            log.warning("OPC UA sign-in refused for user %r", username)
            return None
        return User(role=UserRole.User, name=username)


#: OPC UA Part 8 (https://reference.opcfoundation.org/Core/Part8/v105/docs/5.6.3): units
#: are EUInformation from UNECE Recommendation 20, in this namespace, with UnitId the common
#: code's characters as one integer (each character's 8-bit code, most significant first).
UNECE_NAMESPACE = "http://www.opcfoundation.org/UA/units/un/cefact"


@dataclass(frozen=True)
class Unit:
    """A UNECE unit: common code, symbol, name."""

    code: str
    symbol: str
    name: str

    @property
    def unit_id(self) -> int:
        """Part 8 5.6.3: 'MMT' -> 0x4D4D54 = 5066068."""
        return int.from_bytes(self.code.encode("ascii"), "big")

    def eu_information(self) -> ua.EUInformation:
        return ua.EUInformation(
            NamespaceUri=UNECE_NAMESPACE,
            UnitId=self.unit_id,
            DisplayName=ua.LocalizedText(self.symbol, "en"),
            Description=ua.LocalizedText(self.name, "en"),
        )


MILLIMETRE = Unit("MMT", "mm", "millimetre")
DEGREE = Unit("DD", "°", "degree [unit of angle]")


@dataclass(frozen=True)
class Variable:
    """One variable of a subject: its type, array length (None: a scalar), what it says (its
    Description attribute, in the subject's words: `description`) and its unit (an
    EngineeringUnits property; the variable is then a BaseAnalogType, Part 8 5.3.2)."""

    vtype: ua.VariantType
    length: int | None
    #: `description` with the subject's words as {kind}, {value} and {within}
    text: str
    unit: Unit | None = None

    def description(self, served: Served) -> str:
        """What it says of a subject's item ("The number of the tool's active TCP version")."""
        subject = served.subject
        return self.text.format(kind=subject.kind, value=subject.value, within=served.value_in)


VARIABLES: dict[str, Variable] = {
    "ActiveVersion": Variable(
        ua.VariantType.Int32,
        None,
        "The number of the {kind}'s active {value} version; 0 while the {kind} has none.",
    ),
    "PositionMm": Variable(
        ua.VariantType.Double,
        3,
        "The active {value}'s position x, y, z in {within}, in millimetres (empty "
        "without an active version).",
        MILLIMETRE,
    ),
    "Quaternion": Variable(
        ua.VariantType.Double,
        4,
        "The active {value}'s orientation in {within} as a unit quaternion w, x, y, z "
        "(empty without an active version).",
    ),
    "KukaABC": Variable(
        ua.VariantType.Double,
        3,
        "The active {value}'s orientation as A, B, C (the kuka_abc convention: rotations "
        "about z, y', x''), in degrees (empty without an active version).",
        DEGREE,
    ),
    "Status": Variable(
        ua.VariantType.String,
        None,
        "The active version's status: accepted, or out_of_tolerance (it was put live with "
        "force; see ActivationKind and ActivationReason); empty without an active version.",
    ),
    "ActivationKind": Variable(
        ua.VariantType.String,
        None,
        "How the active version went live: explicit, forced (out of tolerance, with a "
        "reason), rollback, calibration:auto, calibration:always, ...; empty without one.",
    ),
    "ActivationReason": Variable(
        ua.VariantType.String,
        None,
        "The reason the person gave for that activation or rollback; empty when none was given.",
    ),
    "ControllerState": Variable(
        ua.VariantType.String,
        None,
        "What the last reconcile round found on the robot controller: in_sync, drifted, "
        "unreachable, ...; none when it was never looked at.",
    ),
    "UpdatedAt": Variable(
        ua.VariantType.DateTime, None, "When the {kind} last changed in tcpcal (UTC)."
    ),
}


def variable_values(item: PlantItem) -> dict[str, object]:
    """The variables' values for a subject's item (0, empty arrays and empty strings without
    an active version)."""
    activation = item.activation
    return {
        "ActiveVersion": item.active_version or 0,
        "PositionMm": list(item.position_mm or ()),
        "Quaternion": list(item.quaternion or ()),
        "KukaABC": list(item.kuka_abc or ()),
        "Status": item.status or "",
        "ActivationKind": "" if activation is None else activation.kind,
        "ActivationReason": "" if activation is None else activation.reason or "",
        "ControllerState": item.controller_state,
        "UpdatedAt": item.updated_at.astimezone(UTC),
    }


def _standard(identifier: int) -> ua.NodeId:
    """A node of the standard namespace (0) by its numeric id."""
    return ua.NodeId(ua.Int32(identifier))


@dataclass
class _RobotNodes:
    name: str
    folder: Node
    #: each subject's folder of the robot, by subject kind
    groups: dict[str, _GroupNodes]


@dataclass
class _GroupNodes:
    served: Served
    folder: Node
    items: dict[str, _ItemNodes]


@dataclass
class _ItemNodes:
    name: str
    folder: Node
    variables: dict[str, Node]
    values: dict[str, object]


class PlantOpcUaServer:
    """The asyncua server and the address space it keeps equal to the fleet it is given."""

    def __init__(
        self,
        endpoint: str,
        *,
        check: KeyCheck,
        anonymous: bool,
        certificate: ServerCertificate | None = None,
    ) -> None:
        self.endpoint = parse_endpoint(endpoint)
        self._server = Server(user_manager=ApiKeyUsers(check, anonymous=anonymous))
        self._anonymous = anonymous
        self._certificate = certificate
        self._robots: dict[str, _RobotNodes] = {}
        self._ns = 0
        self._root: Node | None = None
        self._lock = asyncio.Lock()

    def _nid(self, name: str) -> ua.NodeId:
        return ua.NodeId(ua.String(name), ua.Int16(self._ns))

    async def start(self, robots: Sequence[PlantRobot] = ()) -> None:
        """Build the address space with these robots, then listen on the endpoint (a client
        never sees it half filled); OpcUaStartError when the port is taken or not bindable."""
        server = self._server
        await server.init()
        server.set_endpoint(self.endpoint.url)
        server.set_server_name("tcpcal")
        await server.set_application_uri(APPLICATION_URI)
        policies = [ua.SecurityPolicyType.NoSecurity]
        if self._certificate is not None:
            cert = self._certificate
            await server.load_certificate(cert.certificate, cert.certificate_format)
            await server.load_private_key(cert.private_key, format=cert.private_key_format)
            policies.append(ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt)
        server.set_security_policy(policies)
        tokens: list[type] = [ua.UserNameIdentityToken]
        if self._anonymous:
            tokens.insert(0, ua.AnonymousIdentityToken)
        server.set_identity_tokens(tokens)
        self._ns = await server.register_namespace(NAMESPACE_URI)
        self._root = await server.nodes.objects.add_folder(
            self._nid("Robots"), ua.QualifiedName("Robots", self._ns)
        )
        await self.replace_all(robots)
        try:
            await server.start()
        except OSError as exc:
            raise OpcUaStartError(
                f"the OPC UA server cannot listen on {self.endpoint.host}:{self.endpoint.port} "
                f"({exc.strerror or exc}): is another server using the port? "
                "Set TCPCAL_OPCUA_ENDPOINT to a free one."
            ) from None

    async def stop(self) -> None:
        """Close every session and stop listening."""
        await self._server.stop()

    async def replace_all(self, robots: Sequence[PlantRobot]) -> None:
        """Make the address space show exactly these robots and what they hold."""
        async with self._lock:
            wanted = {r.robot_id for r in robots}
            for robot_id in [r for r in self._robots if r not in wanted]:
                await self._drop_robot(robot_id)
            for robot in robots:
                await self._apply_robot(robot)

    async def replace_robot(self, robot_id: str, robot: PlantRobot | None) -> None:
        """Make one robot's subtree show this state (None: the robot is gone)."""
        async with self._lock:
            if robot is None:
                await self._drop_robot(robot_id)
            else:
                await self._apply_robot(robot)

    async def _apply_robot(self, robot: PlantRobot) -> None:
        nodes = self._robots.get(robot.robot_id)
        if nodes is not None and nodes.name != robot.name:  # renamed: a new browse name
            await self._drop_robot(robot.robot_id)
            nodes = None
        if nodes is None:
            nodes = await self._add_robot(robot)
        for kind, group in nodes.groups.items():
            wanted = {item.subject_id: item for item in robot.items.get(kind, [])}
            for item_id in [i for i in group.items if i not in wanted]:
                await self._delete_subtree(group.folder, group.items.pop(item_id).folder)
            for item in wanted.values():
                await self._apply_item(group, item)

    async def _add_robot(self, robot: PlantRobot) -> _RobotNodes:
        assert self._root is not None, "start() first"
        folder = await self._root.add_folder(
            self._nid(f"robots/{robot.robot_id}"), ua.QualifiedName(robot.name, self._ns)
        )
        # A folder per subject, named by its declaration (Subject.folder: a robot's "Tools"),
        # every robot having each (empty while it has none of them).
        groups: dict[str, _GroupNodes] = {}
        for served in IN_FLEET:
            name = served.subject.folder
            group = await folder.add_folder(
                self._nid(f"robots/{robot.robot_id}/{name}"), ua.QualifiedName(name, self._ns)
            )
            groups[served.subject.kind] = _GroupNodes(served=served, folder=group, items={})
        nodes = _RobotNodes(name=robot.name, folder=folder, groups=groups)
        self._robots[robot.robot_id] = nodes
        return nodes

    async def _drop_robot(self, robot_id: str) -> None:
        nodes = self._robots.pop(robot_id, None)
        if nodes is not None:
            assert self._root is not None, "start() first"
            await self._delete_subtree(self._root, nodes.folder)

    async def _delete_subtree(self, parent: Node, folder: Node) -> None:
        """Delete `folder` (a robot's or an item's, organized by `parent`) and all below it.
        asyncua's delete with its target references scans the whole address space (the
        standard nodes, some thousands) for every node it deletes: 0.2 s an item, a renamed
        robot with ten items 2.3 s, past the second docs/publishing.md promises. Nothing
        outside a subtree refers into it but its parent (asyncua gives a new node's forward
        reference to its parent alone; the type definition reference is the node's own), so
        that reference goes first (it must name a node that still is), then the nodes go
        without the scan."""
        session = self._server.iserver.isession
        (status,) = await session.delete_references(
            [
                ua.DeleteReferencesItem(
                    SourceNodeId=parent.nodeid,
                    ReferenceTypeId=_standard(ObjectIds.Organizes),
                    IsForward=True,
                    TargetNodeId=folder.nodeid,
                    DeleteBidirectional=False,
                )
            ]
        )
        status.check()
        await delete_nodes(session, [folder], recursive=True, delete_target_references=False)

    async def _apply_item(self, group: _GroupNodes, item: PlantItem) -> None:
        nodes = group.items.get(item.subject_id)
        if nodes is not None and nodes.name != item.name:
            await self._delete_subtree(group.folder, group.items.pop(item.subject_id).folder)
            nodes = None
        values = variable_values(item)
        if nodes is None:
            group.items[item.subject_id] = await self._add_item(group, item, values)
            return
        for name, value in values.items():
            if nodes.values.get(name) != value:
                await self._write(nodes.variables[name], name, value)
        nodes.values = values

    async def _add_item(
        self, group: _GroupNodes, item: PlantItem, values: dict[str, object]
    ) -> _ItemNodes:
        # Node ids named by the subject's declaration (Subject.plural): "tools/<id>/...".
        base = f"{group.served.subject.plural}/{item.subject_id}"
        folder = await group.folder.add_folder(
            self._nid(base), ua.QualifiedName(item.name, self._ns)
        )
        variables: dict[str, Node] = {}
        for name, spec in VARIABLES.items():
            text = spec.description(group.served)
            nid = f"{base}/{name}"
            variables[name] = await self._add_variable(folder, nid, name, spec, text, values)
        return _ItemNodes(name=item.name, folder=folder, variables=variables, values=values)

    async def _add_variable(
        self,
        folder: Node,
        nid: str,
        name: str,
        spec: Variable,
        description: str,
        values: dict[str, object],
    ) -> Node:
        """A read-only variable with its Description, its array's dimensions and, with a
        unit, the type BaseAnalogType and an EngineeringUnits property (asyncua's
        add_variable sets the browse name as the description and takes no type)."""
        attrs = ua.VariableAttributes(
            DisplayName=ua.LocalizedText(name),
            Description=ua.LocalizedText(description, "en"),
            Value=ua.Variant(values[name], spec.vtype),
            DataType=_standard(spec.vtype.value),
            ValueRank=ua.ValueRank.Scalar,
            AccessLevel=ua.AccessLevel.CurrentRead.mask,
            UserAccessLevel=ua.AccessLevel.CurrentRead.mask,
        )
        if spec.length is not None:  # Part 3 5.6.2: a one-dimensional array of this length
            attrs.ValueRank = ua.ValueRank.OneDimension
            attrs.ArrayDimensions = [spec.length]
        typedef = ObjectIds.BaseDataVariableType if spec.unit is None else ObjectIds.BaseAnalogType
        item = ua.AddNodesItem(
            ParentNodeId=folder.nodeid,
            ReferenceTypeId=_standard(ObjectIds.HasComponent),
            RequestedNewNodeId=self._nid(nid),
            BrowseName=ua.QualifiedName(name, self._ns),
            NodeClass=ua.NodeClass.Variable,
            NodeAttributes=attrs,
            TypeDefinition=_standard(typedef),
        )
        (added,) = await self._server.iserver.isession.add_nodes([item])
        added.StatusCode.check()
        node = self._server.get_node(added.AddedNodeId)
        if spec.unit is not None:
            units = await node.add_property(
                self._nid(f"{nid}/EngineeringUnits"),
                ua.QualifiedName("EngineeringUnits", 0),
                ua.Variant(spec.unit.eu_information(), ua.VariantType.ExtensionObject),
                datatype=_standard(ObjectIds.EUInformation),
            )
            await units.write_attribute(
                AttributeIds.Description,
                ua.DataValue(
                    ua.Variant(ua.LocalizedText(f"{spec.unit.name} ({spec.unit.code})", "en"))
                ),
            )
        return node

    async def _write(self, node: Node, name: str, value: object) -> None:
        vtype = VARIABLES[name].vtype
        await self._server.write_attribute_value(
            node.nodeid,
            ua.DataValue(ua.Variant(value, vtype), SourceTimestamp=ua.DateTime.now(UTC)),
        )
