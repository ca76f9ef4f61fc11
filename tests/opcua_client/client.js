// An OPC UA client of another implementation than tcpcal's server (node-opcua, not asyncua),
// driven by tests/publish/test_opcua.py: every value those tests check is read through it.
//
// Usage: node client.js --endpoint opc.tcp://127.0.0.1:PORT/tcpcal/ [--user NAME --password KEY]
//        node client.js --endpoint ... --endpoints        (the server's endpoints, then exit)
//
// It signs in (anonymously without --user), prints {"event": "session"}, then reads one JSON
// command a line on stdin and answers each with JSON lines on stdout, until stdin closes:
//   {"op": "tree"}                -> {"event": "tree", "robots": {<robot>: {<tool>: {<variable>:
//                                    value}}}, "namespace": i}
//   {"op": "tree", "folder": "Frames"} -> the same of each robot's Frames folder (default Tools)
//   {"op": "tree", "details": true} -> the same, with "variables": {"<robot>/<tool>/<variable>":
//                                    {description, dataType, valueRank, arrayDimensions,
//                                    typeDefinition, userAccessLevel, engineeringUnits:
//                                    {namespaceUri, unitId, displayName, description} | null,
//                                    engineeringUnitsDescription}}
//   {"op": "write", "path": "<robot>/<tool>/<variable>", "value": n}
//                                 -> {"event": "write", "status": "<StatusCode name>"}
//   {"op": "add"}                 -> {"event": "add", "status": ...}   (AddNodes: a folder)
//   {"op": "delete", "path": ...} -> {"event": "delete", "status": ...} (DeleteNodes)
//   {"op": "watch", "path": ..., "until": v, "timeout_ms": n}
//                                 -> {"event": "subscribed", "value": v0}, then
//                                    {"event": "changed", "value": v} for each change up to v
// A command that fails answers {"event": "error", "op": ..., "message": ..., "status": ...}
// and the client goes on; a refused sign-in prints an error and exits 3.
"use strict";
const readline = require("readline");
const {
  OPCUAClient, MessageSecurityMode, SecurityPolicy, UserTokenType, AttributeIds,
  BrowseDirection, DataType, StatusCodes, TimestampsToReturn, ClientSubscription,
  ClientMonitoredItem, AddNodesRequest, DeleteNodesRequest, NodeClass,
} = require("node-opcua");

function args(argv) {
  const out = {};
  for (let i = 0; i < argv.length; i++) {
    const key = argv[i].replace(/^--/, "");
    if (i + 1 < argv.length && !argv[i + 1].startsWith("--")) out[key] = argv[++i];
    else out[key] = true;
  }
  return out;
}

function emit(obj) {
  process.stdout.write(JSON.stringify(obj) + "\n");
}

function plain(value) {
  if (value === null || value === undefined) return null;
  if (value instanceof Date) return value.toISOString();
  if (ArrayBuffer.isView(value)) return Array.from(value);
  if (Array.isArray(value)) return value.map(plain);
  return value;
}

function text(localized) {
  return localized ? { text: localized.text, locale: localized.locale } : null;
}

function statusOf(err) {
  const header = err && err.response && err.response.responseHeader;
  return header && header.serviceResult ? header.serviceResult.name : null;
}

async function children(session, nodeId, referenceTypeId = "HierarchicalReferences") {
  const result = await session.browse({
    nodeId, browseDirection: BrowseDirection.Forward, includeSubtypes: true,
    referenceTypeId, resultMask: 63,
  });
  if (!result.statusCode.equals(StatusCodes.Good)) throw new Error(`browse ${nodeId}: ${result.statusCode.name}`);
  return result.references.map((r) => ({ name: r.browseName.name, ns: r.browseName.namespaceIndex, nodeId: r.nodeId }));
}

async function childNamed(session, nodeId, name) {
  const found = (await children(session, nodeId)).find((c) => c.name === name);
  if (!found) throw new Error(`no ${name} under ${nodeId.toString()}`);
  return found;
}

// What a plant client learns about a variable besides its value (OPC UA Part 3 attributes,
// its type definition, and Part 8's EngineeringUnits property when it has one).
async function details(session, nodeId) {
  const ids = [AttributeIds.Description, AttributeIds.DataType, AttributeIds.ValueRank,
    AttributeIds.ArrayDimensions, AttributeIds.UserAccessLevel];
  const [description, dataType, valueRank, dims, access] = await session.read(
    ids.map((attributeId) => ({ nodeId, attributeId })));
  const typeDefinition = (await children(session, nodeId, "HasTypeDefinition"))[0];
  const property = (await children(session, nodeId, "HasProperty")).find((p) => p.name === "EngineeringUnits");
  let engineeringUnits = null;
  let engineeringUnitsDescription = null;
  if (property) {
    const [dv, desc] = await session.read([
      { nodeId: property.nodeId, attributeId: AttributeIds.Value },
      { nodeId: property.nodeId, attributeId: AttributeIds.Description },
    ]);
    const eu = dv.value.value;
    engineeringUnits = {
      namespaceUri: eu.namespaceUri, unitId: eu.unitId,
      displayName: text(eu.displayName), description: text(eu.description),
      propertyNamespace: property.ns,
    };
    engineeringUnitsDescription = text(desc.value.value);
  }
  return {
    description: text(description.value.value),
    dataType: dataType.value.value.toString(),
    valueRank: valueRank.value.value,
    arrayDimensions: plain(dims.value.value),
    typeDefinition: typeDefinition ? typeDefinition.nodeId.toString() : null,
    userAccessLevel: access.value.value,
    engineeringUnits,
    engineeringUnitsDescription,
  };
}

async function readTree(session, withDetails, folder = "Tools") {
  const robotsFolder = await childNamed(session, "ns=0;i=85", "Robots");  // Objects/Robots
  const robots = {};
  const nodes = {};
  const variables = {};
  for (const robot of await children(session, robotsFolder.nodeId)) {
    const tools = await childNamed(session, robot.nodeId, folder);
    robots[robot.name] = {};
    for (const tool of await children(session, tools.nodeId)) {
      const values = {};
      for (const v of await children(session, tool.nodeId)) {
        const path = `${robot.name}/${tool.name}/${v.name}`;
        const dv = await session.read({ nodeId: v.nodeId, attributeId: AttributeIds.Value });
        if (!dv.statusCode.equals(StatusCodes.Good)) throw new Error(`read ${path}: ${dv.statusCode.name}`);
        values[v.name] = plain(dv.value.value);
        nodes[path] = v.nodeId;
        if (withDetails) variables[path] = await details(session, v.nodeId);
      }
      robots[robot.name][tool.name] = values;
    }
  }
  return { robots, nodes, variables, robotsFolder };
}

async function nodeAt(session, path) {
  const tree = await readTree(session, false);
  const nodeId = tree.nodes[path];
  if (!nodeId) throw new Error(`no ${path} in the tree`);
  return nodeId;
}

async function watch(session, command) {
  const nodeId = await nodeAt(session, command.path);
  const subscription = ClientSubscription.create(session, {
    requestedPublishingInterval: 50, requestedLifetimeCount: 600,
    requestedMaxKeepAliveCount: 20, maxNotificationsPerPublish: 100,
    publishingEnabled: true, priority: 10,
  });
  const item = ClientMonitoredItem.create(
    subscription, { nodeId, attributeId: AttributeIds.Value },
    { samplingInterval: 0, discardOldest: true, queueSize: 10 }, TimestampsToReturn.Both,
  );
  const until = command.until;
  const done = new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`no ${command.path} = ${until} within ${command.timeout_ms} ms`)),
      Number(command.timeout_ms || 5000));
    let initial = true;
    item.on("changed", (dv) => {
      const value = plain(dv.value.value);
      if (initial) { initial = false; emit({ event: "subscribed", value }); return; }
      emit({ event: "changed", value });
      if (value === until) { clearTimeout(timer); resolve(); }
    });
  });
  try {
    await done;
  } finally {
    await subscription.terminate();
  }
}

async function run(session, command) {
  if (command.op === "tree") {
    const tree = await readTree(session, Boolean(command.details), command.folder || "Tools");
    const answer = { event: "tree", robots: tree.robots, namespace: tree.robotsFolder.ns };
    if (command.details) answer.variables = tree.variables;
    emit(answer);
  } else if (command.op === "write") {
    const status = await session.write({
      nodeId: await nodeAt(session, command.path), attributeId: AttributeIds.Value,
      value: { value: { dataType: DataType.Int32, value: command.value } },
    });
    emit({ event: "write", status: status.name });
  } else if (command.op === "add") {
    const robotsFolder = await childNamed(session, "ns=0;i=85", "Robots");
    const request = new AddNodesRequest({
      nodesToAdd: [{
        parentNodeId: robotsFolder.nodeId, referenceTypeId: "ns=0;i=35",  // Organizes
        requestedNewNodeId: `ns=${robotsFolder.ns};s=intruder`,
        browseName: { namespaceIndex: robotsFolder.ns, name: "Intruder" },
        nodeClass: NodeClass.Object, typeDefinition: "ns=0;i=61",  // FolderType
      }],
    });
    emit({ event: "add", status: await transactionStatus(session, request) });
  } else if (command.op === "delete") {
    const request = new DeleteNodesRequest({
      nodesToDelete: [{ nodeId: await nodeAt(session, command.path), deleteTargetReferences: true }],
    });
    emit({ event: "delete", status: await transactionStatus(session, request) });
  } else if (command.op === "watch") {
    await watch(session, command);
  } else {
    throw new Error(`unknown op ${command.op}`);
  }
}

// The service's answer to a node management request: the service result when it failed,
// else the first result's status.
function transactionStatus(session, request) {
  return new Promise((resolve) => {
    session.performMessageTransaction(request, (err, response) => {
      if (err) resolve(statusOf(err) || String(err.message).split("\n")[0]);
      else resolve(response.results[0].statusCode.name);
    });
  });
}

async function endpoints(client) {
  const points = await client.getEndpoints();
  emit({
    event: "endpoints",
    points: points.map((p) => ({
      mode: MessageSecurityMode[p.securityMode],
      policy: p.securityPolicyUri,
      tokens: (p.userIdentityTokens || []).map((t) => ({
        type: UserTokenType[t.tokenType], policy: t.securityPolicyUri,
      })),
    })),
  });
}

async function main() {
  const a = args(process.argv.slice(2));
  const client = OPCUAClient.create({
    applicationName: "tcpcal-test-client",
    securityMode: MessageSecurityMode.None,
    securityPolicy: SecurityPolicy.None,
    endpointMustExist: false,
    connectionStrategy: { maxRetry: 2, initialDelay: 200, maxDelay: 500 },
  });
  await client.connect(a.endpoint);
  let session;
  try {
    if (a.endpoints) {
      await endpoints(client);
      return;
    }
    const identity = a.user
      ? { type: UserTokenType.UserName, userName: a.user, password: a.password }
      : { type: UserTokenType.Anonymous };
    try {
      session = await client.createSession(identity);
    } catch (err) {
      emit({ event: "error", op: "sign-in", message: String(err.message).split("\n")[0], status: statusOf(err) });
      process.exitCode = 3;
      return;
    }
    emit({ event: "session" });
    const lines = readline.createInterface({ input: process.stdin });
    for await (const line of lines) {
      if (!line.trim()) continue;
      const command = JSON.parse(line);
      try {
        await run(session, command);
      } catch (err) {
        emit({ event: "error", op: command.op, message: String(err && err.message ? err.message : err).split("\n")[0], status: statusOf(err) });
      }
    }
  } finally {
    if (session) await session.close();
    await client.disconnect();
  }
}

main().catch((err) => {
  emit({ event: "error", op: "connect", message: String(err && err.message ? err.message : err).split("\n")[0], status: null });
  process.exitCode = 2;
});
