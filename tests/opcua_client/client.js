// An OPC UA client of another implementation than tcpcal's server (node-opcua, not asyncua),
// driven by tests/publish/test_opcua.py. It prints one JSON object per line on stdout:
//   {"event": "tree", "robots": {<robot>: {<tool>: {<variable>: value, ...}}}, "namespace": i}
//   {"event": "write", "status": "<StatusCode name>"}   (a client's write attempt)
//   {"event": "subscribed"}                              (watching --watch's ActiveVersion)
//   {"event": "changed", "value": <ActiveVersion>}       (a change seen by the subscription)
//   {"event": "error", "message": "...", "status": "<StatusCode name>"}
// Usage: node client.js --endpoint opc.tcp://127.0.0.1:PORT/tcpcal/ [--user NAME --password KEY]
//                       [--watch ROBOT/TOOL --until VERSION --timeout-ms 5000]
"use strict";
const {
  OPCUAClient, MessageSecurityMode, SecurityPolicy, UserTokenType, AttributeIds,
  BrowseDirection, DataType, StatusCodes, TimestampsToReturn, ClientSubscription,
  ClientMonitoredItem,
} = require("node-opcua");

function args(argv) {
  const out = {};
  for (let i = 0; i < argv.length; i += 2) out[argv[i].replace(/^--/, "")] = argv[i + 1];
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

async function children(session, nodeId) {
  const result = await session.browse({
    nodeId, browseDirection: BrowseDirection.Forward, includeSubtypes: true,
    referenceTypeId: "HierarchicalReferences", resultMask: 63,
  });
  if (!result.statusCode.equals(StatusCodes.Good)) throw new Error(`browse ${nodeId}: ${result.statusCode.name}`);
  return result.references.map((r) => ({ name: r.browseName.name, ns: r.browseName.namespaceIndex, nodeId: r.nodeId }));
}

async function childNamed(session, nodeId, name) {
  const found = (await children(session, nodeId)).find((c) => c.name === name);
  if (!found) throw new Error(`no ${name} under ${nodeId.toString()}`);
  return found;
}

async function readTree(session) {
  const robotsFolder = await childNamed(session, "ns=0;i=85", "Robots");  // Objects/Robots
  const robots = {};
  const nodes = {};
  for (const robot of await children(session, robotsFolder.nodeId)) {
    const tools = await childNamed(session, robot.nodeId, "Tools");
    robots[robot.name] = {};
    for (const tool of await children(session, tools.nodeId)) {
      const values = {};
      for (const v of await children(session, tool.nodeId)) {
        const dv = await session.read({ nodeId: v.nodeId, attributeId: AttributeIds.Value });
        values[v.name] = plain(dv.value.value);
        nodes[`${robot.name}/${tool.name}/${v.name}`] = v.nodeId;
      }
      robots[robot.name][tool.name] = values;
    }
  }
  return { robots, nodes, namespace: robotsFolder.ns };
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
    const identity = a.user
      ? { type: UserTokenType.UserName, userName: a.user, password: a.password }
      : { type: UserTokenType.Anonymous };
    try {
      session = await client.createSession(identity);
    } catch (err) {
      const status = (err.response && err.response.responseHeader && err.response.responseHeader.serviceResult)
        ? err.response.responseHeader.serviceResult.name : null;
      emit({ event: "error", message: String(err.message).split("\n")[0], status });
      process.exitCode = 3;
      return;
    }
    const tree = await readTree(session);
    emit({ event: "tree", robots: tree.robots, namespace: tree.namespace });
    const first = Object.keys(tree.nodes).find((k) => k.endsWith("/ActiveVersion"));
    if (first) {
      const status = await session.write({
        nodeId: tree.nodes[first], attributeId: AttributeIds.Value,
        value: { value: { dataType: DataType.Int32, value: 99 } },
      });
      emit({ event: "write", status: status.name });
    }
    if (a.watch) await watch(session, tree, a);
  } finally {
    if (session) await session.close();
    await client.disconnect();
  }
}

async function watch(session, tree, a) {
  const nodeId = tree.nodes[`${a.watch}/ActiveVersion`];
  if (!nodeId) throw new Error(`no ${a.watch}/ActiveVersion in the tree`);
  const subscription = ClientSubscription.create(session, {
    requestedPublishingInterval: 50, requestedLifetimeCount: 600,
    requestedMaxKeepAliveCount: 20, maxNotificationsPerPublish: 100,
    publishingEnabled: true, priority: 10,
  });
  const item = ClientMonitoredItem.create(
    subscription, { nodeId, attributeId: AttributeIds.Value },
    { samplingInterval: 0, discardOldest: true, queueSize: 10 }, TimestampsToReturn.Both,
  );
  const until = Number(a.until);
  const done = new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`no ActiveVersion ${until} within ${a["timeout-ms"]} ms`)),
      Number(a["timeout-ms"] || 5000));
    let initial = true;
    item.on("changed", (dv) => {
      const value = plain(dv.value.value);
      if (initial) { initial = false; emit({ event: "subscribed", value }); return; }
      emit({ event: "changed", value });
      if (value === until) { clearTimeout(timer); resolve(); }
    });
  });
  await done;
  await subscription.terminate();
}

main().catch((err) => {
  emit({ event: "error", message: String(err && err.message ? err.message : err).split("\n")[0], status: null });
  process.exitCode = 2;
});
