// The tcpcal console: three pages over the JSON API (fleet, tool, calibration report).
// The API key is asked for once, kept in sessionStorage (this browser tab's session) and sent
// as a Bearer header; it never appears in a URL. Every figure is in mm to 3 decimals.

import { calibratePage } from "./calibrate.js";
import { frameCalibratePage } from "./frame_calibrate.js";

const KEY_STORE = "tcpcal.api_key";
const SCOPES = ["read", "calibrate", "admin"];
const main = document.getElementById("main");
// The signed-in key's name and scope (GET /v1/keys/me): write buttons only for what it may do.
let me = null;
const mayCalibrate = () => me !== null && SCOPES.indexOf(me.scope) >= SCOPES.indexOf("calibrate");
const mayAdminister = () => me !== null && me.scope === "admin";

// ---- DOM ------------------------------------------------------------------------------------
function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs)) {
    if (value === null || value === undefined || value === false) continue;
    if (name.startsWith("on")) el.addEventListener(name.slice(2), value);
    else if (name === "class") el.className = value;
    else el.setAttribute(name, value === true ? "" : String(value));
  }
  for (const child of children.flat()) {
    if (child === null || child === undefined || child === false) continue;
    el.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return el;
}

// Optional sections are written `cond ? node : null`; replaceChildren would print a null as
// the text "null" (a manual calibration's report showed "null" and "nullnull").
function show(...nodes) {
  main.replaceChildren(...nodes.filter((node) => node !== null && node !== undefined && node !== false));
}

const mm = (v) => (v === null || v === undefined ? "—" : Number(v).toFixed(3));
const vec = (v) => (v ? v.map(mm).join(", ") : "—");
const when = (iso) => (iso ? new Date(iso).toLocaleString() : "—");
// A moment in a badge: "22:29" today, else its date and time.
function clock(iso) {
  const d = new Date(iso);
  if (d.toDateString() === new Date().toDateString()) return d.toLocaleTimeString([], { hour: "2-digit", minute: "2-digit" });
  return d.toLocaleString([], { dateStyle: "short", timeStyle: "short" });
}

function age(iso) {
  if (!iso) return "—";
  const minutes = (Date.now() - new Date(iso).getTime()) / 60000;
  if (minutes < 1) return "now";
  if (minutes < 60) return `${Math.round(minutes)} min`;
  const days = minutes / 1440;
  if (days < 1) return `${Math.round(days * 24)} h`;
  if (days < 60) return `${Math.round(days)} d`;
  return `${Math.round(days / 30.4)} mo`;
}

// A message about a click goes where the eye is: in a row right under the clicked button's row
// (it was drawn at the top of the page, out of sight of a button further down), scrolled into
// view. One such note per table: a new one replaces the last.
function noteBeside(button, node) {
  const row = button.closest("tr");
  if (!row) {
    button.after(node);
    return;
  }
  row.closest("tbody").querySelectorAll("tr.row-note").forEach((old) => old.remove());
  const note = h("tr", { class: "row-note" }, h("td", { colspan: row.children.length }, node));
  row.after(note);
  note.scrollIntoView({ block: "nearest" });
}

function badge(status) {
  const label = { accepted: "accepted", out_of_tolerance: "out of tolerance" }[status] ?? status;
  return h("span", { class: `badge ${status}` }, label);
}

// ---- API ------------------------------------------------------------------------------------
class Problem extends Error {
  constructor(status, doc) {
    super(doc.detail || doc.title || `HTTP ${status}`);
    this.status = status;
    this.doc = doc;
  }
}

async function api(path, { method = "GET", body, headers = {}, accept = "application/json" } = {}) {
  const init = {
    method,
    headers: { Authorization: `Bearer ${sessionStorage.getItem(KEY_STORE)}`, Accept: accept, ...headers },
  };
  if (body !== undefined) {
    init.body = JSON.stringify(body);
    init.headers["Content-Type"] = "application/json";
  }
  const response = await fetch(path, init);
  if (!response.ok) {
    let doc = {};
    try {
      doc = await response.json();
    } catch {
      doc = { title: response.statusText };
    }
    if (response.status === 401) sessionStorage.removeItem(KEY_STORE);
    throw new Problem(response.status, doc);
  }
  return response;
}

const json = async (path, options) => (await api(path, options)).json();

async function everyPage(path) {
  const items = [];
  let cursor = null;
  do {
    const sep = path.includes("?") ? "&" : "?";
    const page = await json(`${path}${sep}limit=500${cursor ? `&cursor=${cursor}` : ""}`);
    items.push(...page.items);
    cursor = page.next_cursor;
  } while (cursor);
  return items;
}

function problemBox(error) {
  if (!(error instanceof Problem)) return h("div", { class: "problem", role: "alert" }, String(error));
  const doc = error.doc;
  const fields = (doc.errors || []).map((e) =>
    h("li", {}, `${(e.loc || []).join(".")}: ${e.msg || e.message || ""}`),
  );
  return h(
    "div",
    { class: "problem", role: "alert" },
    h("strong", {}, `${error.status} ${doc.title || ""}`),
    h("p", {}, doc.detail || ""),
    fields.length ? h("ul", {}, fields) : null,
  );
}

async function download(path, accept, fallbackName) {
  const response = await api(path, { accept });
  const disposition = response.headers.get("Content-Disposition") || "";
  const match = disposition.match(/filename="([^"]+)"/);
  const url = URL.createObjectURL(await response.blob());
  const link = h("a", { href: url, download: match ? match[1] : fallbackName });
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}

async function copyText(text, button) {
  try {
    await navigator.clipboard.writeText(text);
  } catch {
    // Plain http on a cell network is not a secure context: fall back to a selection.
    const area = h("textarea", { class: "offscreen" }, text);
    document.body.append(area);
    area.select();
    document.execCommand("copy");
    area.remove();
  }
  button.textContent = "Copied";
  setTimeout(() => (button.textContent = "Copy"), 1500);
}

// ---- sign in --------------------------------------------------------------------------------
function signIn(then, message) {
  const form = h(
    "form",
    { id: "sign-in", class: "card narrow", autocomplete: "off" },
    h("h1", {}, "Sign in"),
    h("p", {}, "Paste an API key (read scope is enough to look; calibrate to activate). It is kept for this browser session only."),
    h("label", { for: "api_key" }, "API key"),
    h("input", { id: "api_key", name: "api_key", type: "password", required: true, autofocus: true }),
    h("button", { type: "submit" }, "Sign in"),
    message ? h("p", { class: "problem", role: "alert" }, message) : null,
  );
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    main.setAttribute("aria-busy", "true");
    sessionStorage.setItem(KEY_STORE, form.elements.api_key.value.trim());
    try {
      me = await json("/v1/keys/me");
      then();
    } catch (error) {
      sessionStorage.removeItem(KEY_STORE);
      signIn(then, error instanceof Problem && error.status === 401
        ? "This key is not accepted: it is unknown or revoked. Ask an admin for a key (tcpcal keys create)."
        : error.message);
    }
  });
  show(form);
  main.setAttribute("aria-busy", "false");
  document.getElementById("sign-out").hidden = true;
}

// ---- fleet ----------------------------------------------------------------------------------
// What each attention code of GET /v1/tools means, for the row's tooltip.
const ATTENTION = {
  active_out_of_tolerance: "the version controllers are served was stored out of tolerance",
  last_calibration_out_of_tolerance: "the last calibration is out of tolerance",
  check_failed: "the last check found the TCP out of tolerance",
  no_active_version: "no active TCP: calibrate or activate a version",
  stale: "neither calibrated nor checked for a long time (TCPCAL_STALE_DAYS)",
  controller_drifted: "the robot's controller holds another TCP than the active one (deploy, or find out who changed it)",
  controller_unreachable: "the robot's controller could not be read at the last look",
  drifting: "the drift trend leaves check_mm within 30 days at 95 % confidence",
  moving_by_stale_version: "the robot moves by an older version of this tool, not the active one (deploy, or find which program sets $TOOL)",
  moving_by_unknown_tcp: "the robot moves by a TCP no version of its tools has",
  frequent_corrections: "re-checks corrected the TCP more than TCPCAL_CORRECTIONS_ALERT times in 30 days: the tool keeps getting hit",
};

// A drift rate as "0.274 ± 0.012 mm/month" (docs/drift.md).
const rate = (value, sigma) => `${value.toFixed(3)} ± ${sigma.toFixed(3)} mm/month`;

async function fleetPage() {
  document.title = "Fleet · tcpcal";
  const all = await everyPage("/v1/tools");
  const cells = [...new Set(all.map((t) => t.cell).filter(Boolean))].sort();
  const filters = h(
    "form",
    { class: "filters", role: "search" },
    h("label", {}, "Search ", h("input", { name: "q", type: "search", placeholder: "tool or robot name" })),
    h("label", {}, "Cell ", h("select", { name: "cell" }, h("option", { value: "" }, "all"), cells.map((c) => h("option", { value: c }, c)))),
    h(
      "label",
      {},
      "Last calibration ",
      h("select", { name: "status" }, h("option", { value: "" }, "any"), h("option", { value: "accepted" }, "accepted"), h("option", { value: "out_of_tolerance" }, "out of tolerance")),
    ),
    h("label", {}, h("input", { name: "attention", type: "checkbox" }), " needs attention only"),
    h("button", { type: "button", id: "csv" }, "Download CSV"),
  );
  const summary = h("p", { id: "fleet-summary" });
  const body = h("tbody");
  const table = h(
    "table",
    { id: "fleet" },
    h("thead", {}, h("tr", {}, FLEET_COLUMNS.map((c) => h("th", {}, c)))),
    body,
  );
  show(h("h1", {}, "Fleet"), filters, summary, table);

  const query = () => {
    const params = new URLSearchParams();
    for (const name of ["q", "cell", "status"]) {
      const value = filters.elements[name].value.trim();
      if (value) params.set(name, value);
    }
    if (filters.elements.attention.checked) params.set("attention", "true");
    return params.toString();
  };
  const render = (tools) => {
    const flagged = tools.filter((t) => t.attention.length).length;
    summary.textContent = `${tools.length} ${tools.length === 1 ? "tool" : "tools"}, ${flagged} ${flagged === 1 ? "needs" : "need"} attention`;
    body.replaceChildren(...tools.map((t) => fleetRow(t, all)));
  };
  let pending = 0;
  const refresh = async () => {
    const mine = ++pending;
    const q = query();
    const tools = q ? await everyPage(`/v1/tools?${q}`) : all;
    if (mine === pending) render(tools);
  };
  filters.addEventListener("input", () => refresh().catch((e) => summary.replaceChildren(problemBox(e))));
  filters.addEventListener("submit", (e) => e.preventDefault());
  filters.querySelector("#csv").addEventListener("click", () => {
    const q = query();
    download(`/v1/tools${q ? `?${q}` : ""}`, "text/csv", "tcpcal-fleet.csv").catch((e) => summary.replaceChildren(problemBox(e)));
  });
  render(all);
}

// The fleet table's columns; below 1100 px each row is a card whose cells carry these as
// labels (data-label), so a 768 px tablet never scrolls sideways (the table was 909-1202 px).
const FLEET_COLUMNS = ["Tool", "Robot", "Cell", "Slot", "Active", "Last calibration", "rms mm", "Age", "Last check", "Controller", "Moving by", "Drift", "Attention"];

function fleetRow(tool, fleet) {
  const row = fleetCells(tool, fleet);
  [...row.children].forEach((td, i) => td.setAttribute("data-label", FLEET_COLUMNS[i]));
  return row;
}

function fleetCells(tool, fleet) {
  const last = tool.last_calibration;
  const check = tool.last_check;
  const codes = tool.attention;
  return h(
    "tr",
    { class: codes.length ? "attention" : null, "data-tool-id": tool.id },
    h("td", {}, h("a", { href: `/ui/tools/${tool.id}` }, tool.name)),
    h("td", {}, tool.robot_name),
    h("td", {}, tool.cell ?? "—"),
    h("td", { class: "num" }, tool.slot ?? "—"),
    h("td", { class: "num" }, tool.active_version ?? "none"),
    h("td", {}, last ? h("a", { href: `/ui/calibrations/${last.id}` }, badge(last.status)) : "never"),
    h("td", { class: "num" }, last ? mm(last.rms_mm) : "—"),
    h("td", { class: "num", title: last ? when(last.created_at) : "" }, last ? age(last.created_at) : "—"),
    h("td", { class: "last-check" }, checkBadge(check)),
    h("td", { class: "controller-state" }, controllerBadge(tool.controller, { degrees: true, active: tool.active_version })),
    h("td", { class: "live-state", "data-state": tool.live?.no_tool ? "no_tool" : tool.live?.state ?? null, title: liveTitle(tool.live) }, movingBy(tool, fleet) ?? "—"),
    h("td", { class: "num drift", title: tool.drift ? `from the ${tool.drift.basis}${tool.drift.crosses_check_at ? `; out of check_mm by ${when(tool.drift.crosses_check_at)}` : ""}` : "fewer than three points over a day" },
      tool.drift ? rate(tool.drift.rate_mm_per_month, tool.drift.sigma_mm_per_month) : "—"),
    h("td", { class: "reasons", title: codes.map((c) => ATTENTION[c] ?? c).join("; ") },
      codes.map((c) => h("span", { class: "code", "data-code": c }, c))),
  );
}

// The fleet's last check: "pass 0.120", "fail 0.808", or a re-check that corrected the TCP
// as the correction it was, "corrected 0.808 → v7" (it showed as a red "fail 0.808").
function checkBadge(check) {
  if (!check) return "—";
  const distance = mm(check.distance_mm);
  if (check.verdict === "corrected" || check.verdict === "deployment_failed") {
    const to = check.correction_version === null || check.correction_version === undefined ? "" : ` → v${check.correction_version}`;
    const failed = check.verdict === "deployment_failed";
    const title = `the re-check found the TCP ${distance} mm off and made${to ? ` v${check.correction_version}` : " a new version"} of it, active${failed ? ", but its deployment to the controller failed: see the Controller column" : " and deployed"}`;
    return h("span", { class: `badge check ${check.verdict}`, title }, `corrected ${distance}${to}${failed ? ", not deployed" : ""}`);
  }
  return h("span", { class: `badge ${check.within_tolerance ? "accepted" : "out_of_tolerance"}` }, `${check.within_tolerance ? "pass" : "fail"} ${distance}`);
}

// Which TCP the row's robot moves by right now (contract v1.3 fleet rows' `live`, from the
// reconcile rounds), in words: "moving by torch v7, active", "moving by torch v6: not the
// active v7", "moving by a TCP no version has". `fleet` holds the rows another tool's name is
// found in. Null for a server without `live`.
function movingBy(row, fleet) {
  const live = row.live;
  if (!live) return null;
  if (live.state === "active") return `moving by ${row.name} v${live.version}, active`;
  if (live.state === "stale_version") {
    return `moving by ${row.name} v${live.version}: not the active ${row.active_version === null ? "version (none is active)" : `v${row.active_version}`}`;
  }
  if (live.state === "other_tool") {
    const other = fleet.find((t) => t.id === live.tool_id);
    return `moving by ${other ? other.name : "another tool"} v${live.version}, not ${row.name}`;
  }
  if (live.state === "unknown" && live.no_tool) return NO_TOOL;
  if (live.state === "unknown") return live.number === null || live.number === undefined ? "moving by a TCP no version has" : `moving by tool ${live.number}: a TCP no version has`;
  return live.checked_at ? "not known" : null;
}
// A robot at its bare flange (tool 0, or its maker's null tool), as robots idle between jobs.
// Read after "The robot is " on the tool page as well.
const NO_TOOL = "at its bare flange: no tool selected";
const liveTitle = (live) => {
  if (!live) return "";
  if (!live.checked_at) return LIVE_NEVER;
  if (live.no_tool) return `the robot moves by its bare flange: no tool is selected, as between jobs (not an unknown TCP); read ${when(live.checked_at)}`;
  return `${live.state === "unread" ? `${LIVE_UNREAD}; ` : ""}read ${when(live.checked_at)}`;
};
// Why a robot's live TCP is "not known", or not shown.
const LIVE_UNREAD = "the controller does not say which TCP it moves by, or could not be read at the last look";
const LIVE_NEVER = "no reconcile round has read this robot's controller yet";

// ---- controllers ----------------------------------------------------------------------------
// Where the controller is reached: host:port, or for a protocol of several services
// (its declared services, as `ports`) each service's port, as the API answers them.
function controllerAddress(connection) {
  if (!connection.ports) return `${connection.host}:${connection.port}`;
  return `${connection.host} (${Object.entries(connection.ports).map(([name, port]) => `${name} ${port}`).join(", ")})`;
}

const CONTROLLER_LABELS = {
  in_sync: "in sync",
  drifted: "drifted",
  unreachable: "unreachable",
  no_active_version: "no active TCP",
  not_live: "not live",
};

// What a `live` scope deployment means (contract v1.3), for the person at the cell.
const LIVE_SCOPE = "The robot holds this TCP only for the running program: the next program start sets its own TCP, and the reconcile rounds then show what the robot moves by.";
// What a robot of live scope holds, on its tools' pages, before anything is deployed.
const LIVE_ROBOT = "This robot moves by one live TCP: a deployment sets it for the running program only, the next program start sets its own TCP, and the reconcile rounds then show what the robot moves by.";
// Why a tool of a robot with one live TCP is not judged (also when nothing was deployed yet).
const NOT_LIVE = "the robot has one live TCP, and this tool is not the one deployed to it last: deploy this one to make it the live one";

// A drifted badge gives the distance; with `degrees` (the fleet's cell) the angle too when the
// controller's TCP turned: an orientation-only pendant edit read "drifted 0.000 mm". `active`:
// the tool's active version. A look taken before it became active says which version it
// compared, and when: "v5 in sync at 22:29; v6 not compared yet" (it said "in sync", beside
// "moving by torch v5: not the active v6").
function controllerBadge(controller, { degrees = false, active = null } = {}) {
  if (!controller) return "—";
  const label = CONTROLLER_LABELS[controller.state] ?? controller.state;
  const turned = degrees ? turnedBy(controller.deviation_deg) : "";
  const deviation = controller.state === "drifted" ? ` ${mm(controller.deviation_mm)} mm${turned}` : "";
  const compared = controller.version ?? null;
  const where = controller.target ? `${controller.target} ` : "the controller ";
  if (active !== null && compared !== null && compared !== active) {
    const title = `the last look, ${when(controller.checked_at)}, compared ${where}with v${compared}, the active version then; nothing has compared it with v${active} since: deploy v${active}, or reconcile the robot`;
    return h("span", { class: "badge controller earlier", "data-state": controller.state, title },
      `v${compared} ${label}${deviation} at ${clock(controller.checked_at)}; v${active} not compared yet`);
  }
  const against = compared === null ? "" : ` against v${compared}`;
  const title = `${where}checked ${when(controller.checked_at)}${against}${controller.state === "not_live" ? `: ${NOT_LIVE}` : ""}`;
  return h("span", { class: `badge controller ${controller.state}`, "data-state": controller.state, title }, label + deviation);
}

// ", 0.500 deg", or nothing when the angle is none at the figures shown (3 decimals).
function turnedBy(deg) {
  if (deg === null || deg === undefined) return "";
  const figure = Number(deg).toFixed(3);
  return figure === "0.000" ? "" : `, ${figure} deg`;
}

// A frame on two lines (position, then orientation), each kept whole: on one line it was
// 420 px that could not wrap and pushed the deployments table past a 1400 px window.
const frameText = (f) => (f ? [h("span", { class: "line" }, vec(f.position_mm)), h("span", { class: "line" }, `q ${f.quaternion.map((v) => v.toFixed(5)).join(", ")}`)] : "—");

// The version whose TCP a frame is (within 0.01 mm and 0.01 deg, as the live tool's matches),
// as "v6"; else null.
function versionOf(frame, versions) {
  if (!frame) return null;
  const match = versions.find((v) => {
    const off = Math.hypot(...v.tcp.position_mm.map((p, i) => p - frame.position_mm[i]));
    const dot = Math.abs(v.tcp.quaternion.reduce((sum, q, i) => sum + q * frame.quaternion[i], 0));
    return off <= 0.01 && (2 * Math.acos(Math.min(1, dot)) * 180) / Math.PI <= 0.01;
  });
  return match ? `v${match.version}` : null;
}

// What each deployment status (contract v1.3) means at the cell, in words a technician acts
// on. The server's `detail` of a failure ends with these words (and names the version held
// before from its records); a row whose detail does not say them (one recorded before v1.3, a
// read-back mismatch) gets them here.
const DEPLOYMENT_LABELS = { verified: "verified", not_written: "not written", unverified: "written, not confirmed", mismatch: "reads back otherwise" };
// (A detail recorded before v1.3 ends "; nothing was written" alone: the words follow it.)
const DEPLOYMENT_SAID = { not_written: "nothing was written: the controller still holds what it held", unverified: "written, not confirmed" };
function deploymentWords(d, versions) {
  if (d.status === "verified") return `the controller holds v${d.version} (read back within ${d.deviation_mm.toFixed(4)} mm, ${d.deviation_deg.toFixed(4)} deg)`;
  if (d.status === "not_written") return "nothing was written: the controller still holds what it held";
  if (d.status === "unverified") {
    const before = versionOf(d.previous, versions) ?? (d.previous ? "the frame it held before" : "what it held before");
    return `written, not confirmed: the controller may hold v${d.version} or ${before}; the next reconcile round will tell`;
  }
  if (d.status === "mismatch" && d.deviation_mm !== null) {
    return `written, but the controller reads back ${d.deviation_mm.toFixed(4)} mm and ${d.deviation_deg.toFixed(4)} deg off v${d.version}: it does not hold v${d.version}; deploy again, or look on the pendant`;
  }
  return d.status;
}
const saysStatus = (detail, status) => Boolean(detail && DEPLOYMENT_SAID[status] && detail.includes(DEPLOYMENT_SAID[status]));

// `settled`: what the reconcile round after an unverified deployment found the controller
// holding (the deployed version, the frame it held before, or neither), and when.
function settledText(d, versions) {
  const s = d.settled;
  if (!s) return null;
  const before = versionOf(d.previous, versions);
  const holds = {
    written: `the controller holds v${d.version}`,
    previous: `the controller holds what it held before${before ? ` (${before})` : ""}: v${d.version} did not take`,
    other: `the controller holds neither v${d.version} nor what it held before`,
  }[s.holds] ?? s.holds;
  return `Settled ${when(s.at)}: ${holds}`;
}

function deploymentBadge(status) {
  return h("span", { class: `badge deploy ${status}` }, DEPLOYMENT_LABELS[status] ?? status);
}

function deploymentRow(d, versions) {
  const detail = d.error?.detail;
  const settled = settledText(d, versions);
  return h("tr", { "data-deployment": d.id, "data-status": d.status, class: d.status === "verified" ? null : "failed" },
    h("td", {}, when(d.created_at)),
    h("td", { class: "num" }, d.version),
    h("td", { class: "target anywhere" }, d.target, d.scope === "live" ? h("span", { class: "scope muted", title: LIVE_SCOPE }, " (live)") : null),
    h("td", { class: "outcome" },
      deploymentBadge(d.status),
      saysStatus(detail, d.status) ? null : h("p", { class: "words" }, deploymentWords(d, versions)),
      detail ? h("p", { class: "detail anywhere" }, detail) : null,
      settled ? h("p", { class: "settled" }, settled) : null),
    h("td", { class: "num frame" }, frameText(d.previous)),
    h("td", { class: "num" }, d.deviation_mm === null ? "—" : `${d.deviation_mm.toFixed(4)} mm, ${d.deviation_deg.toFixed(4)} deg`),
    h("td", {}, d.actor, d.reason ? h("p", { class: "reason" }, `Why: ${d.reason}`) : null));
}

// Every deployment of a subject, newest first (`versions`: a tool's, to name what it held before).
function deploymentsTable(deployments, versions) {
  return deployments.length
    ? h("table", { id: "deployments" }, h("thead", {}, h("tr", {}, ["When", "Version", "Target", "Outcome", "Held before", "Read back off by", "By"].map((c) => h("th", {}, c)))), h("tbody", {}, deployments.map((d) => deploymentRow(d, versions))))
    : h("p", { id: "no-deployments" }, "Never deployed from tcpcal.");
}

// The tool page's controller section: the state found at the last look, the connection, a
// Deploy button that asks for confirmation first, and every deployment, newest first.
async function controllerSection(tool, versions, onChange) {
  const section = h("section", { id: "controller" }, h("h2", {}, "Controller"));
  const connection = await controllerOf(tool.robot_id);
  const [rows, deployments, points] = await Promise.all([
    everyPage(`/v1/tools?robot_id=${tool.robot_id}`),
    everyPage(`/v1/tools/${tool.id}/deployments`),
    connection && mayCalibrate() ? everyPage(`/v1/robots/${tool.robot_id}/reference-points`) : [],
  ]);
  const state = rows.find((r) => r.id === tool.id)?.controller ?? null;
  if (!connection) {
    section.append(h("p", { id: "controller-none" }, mayAdminister()
      ? "This robot has no controller connection: connect it below to deploy and watch its TCPs."
      : "This robot has no controller connection: an admin connects it (on this page or with tcpcal connect) to deploy and watch its TCPs."));
  } else {
    section.append(controllerStateLine(connection, state, tool.active_version));
    // A robot with one live TCP (a `live` scope) says what that means, and why a tool is not live.
    if (connection.scope === "live") section.append(h("p", { id: "controller-scope", class: "muted" }, LIVE_ROBOT));
    if (state?.state === "not_live") section.append(h("p", { id: "controller-not-live" }, `Not live: ${NOT_LIVE}.`));
    const row = rows.find((r) => r.id === tool.id);
    const moving = row ? movingBy(row, rows) : null;
    if (moving) {
      section.append(h("p", { id: "live-tool", "data-state": row.live.no_tool ? "no_tool" : row.live.state, class: ["stale_version", "unknown", "other_tool"].includes(row.live.state) && !row.live.no_tool ? "attention" : null },
        h("strong", {}, "The robot is "), moving, row.live.state === "unread" ? `: ${LIVE_UNREAD}` : "",
        h("span", { class: "muted" }, ` · read ${when(row.live.checked_at)}`)));
    }
    section.append(deployControls(toolSubject(tool), connection, onChange));
    if (points.length && tool.active_version !== null) section.append(recheckControls(tool, points, versions));
  }
  if (mayAdminister()) section.append(connectionForm(tool, connection, onChange));
  section.append(
    h("h3", {}, "Deployments"),
    deploymentsTable(deployments, versions),
  );
  return section;
}

// After a refused deployment: its status (the 502's `deployment_status`) as a headline, then
// the server's detail, which says what the controller may hold now in words.
function deployProblem(error) {
  const status = error instanceof Problem ? error.doc.deployment_status : undefined;
  if (!DEPLOYMENT_LABELS[status]) return problemBox(error);
  const label = DEPLOYMENT_LABELS[status];
  return h("div", { class: "problem", role: "alert", "data-status": status },
    h("strong", { class: "status" }, `${label[0].toUpperCase()}${label.slice(1)}`),
    h("p", { class: "detail anywhere" }, error.doc.detail || ""),
    h("p", { class: "muted" }, `${error.status} ${error.doc.title || ""} · deployment ${error.doc.deployment_id ?? "not recorded"}`));
}

// The robot's controller connection, or null where it has none.
async function controllerOf(robotId) {
  try {
    return await json(`/v1/robots/${robotId}/controller`);
  } catch (error) {
    // /no-controller: 409 up to v1.2, 404 from contract v1.3 on.
    if (!(error instanceof Problem) || !String(error.doc.type || "").endsWith("/no-controller")) throw error;
    return null;
  }
}

// What the last look found at the controller for a subject (a tool or a frame): the state, the
// version it compared and when.
function controllerStateLine(connection, state, active) {
  return h("p", { id: "controller-state" },
    `${connection.protocol} at ${controllerAddress(connection)} · `,
    state ? controllerBadge(state, { active }) : "not compared yet",
    state ? ` · checked ${when(state.checked_at)}${state.version === null || state.version === undefined ? "" : ` against v${state.version}`}` : "");
}

// What the Deploy button deploys: a tool's active TCP, or a frame's active frame (its
// `moves`: what the robot does by it once written).
const toolSubject = (tool) => ({ name: tool.name, active: tool.active_version, deployments: `/v1/tools/${tool.id}/deployments`, moves: "The robot moves by this TCP from then on." });
const frameSubject = (frame) => ({ name: frame.name, active: frame.active_version, deployments: `/v1/frames/${frame.id}/deployments`, moves: "The robot moves in this frame from then on." });

// A frame no remote interface of the controller writes (501 /no-frame-writer):
// why, and the file to load by hand, in words.
function noWriterBox(error) {
  return h("div", { class: "problem", role: "alert", "data-status": "no_frame_writer" },
    h("strong", { class: "status" }, "Not written: tcpcal cannot write this frame into this controller"),
    h("p", { class: "reason" }, `Why: ${error.doc.reason}.`),
    h("p", { class: "file" }, `Load ${error.doc.file} on the controller by hand instead; nothing was sent.`));
}

function deployControls(subject, connection, onChange) {
  const box = h("div", { id: "deploy" });
  const outcome = h("div", { id: "deploy-outcome" });
  if (subject.active === null) {
    box.append(h("p", { class: "muted" }, "No active version to deploy."));
    return box;
  }
  const ask = h("button", { type: "button", id: "deploy-button" }, `Deploy version ${subject.active}`);
  const confirmBox = h("div", { id: "deploy-confirm", class: "card", hidden: true },
    h("p", {}, `Write version ${subject.active} of ${subject.name} into the controller at ${controllerAddress(connection)} (${connection.protocol}) and read it back? ${connection.scope === "live" ? LIVE_SCOPE : subject.moves}`));
  const yes = h("button", { type: "button", id: "deploy-yes" }, "Deploy now");
  const no = h("button", { type: "button", id: "deploy-no" }, "Cancel");
  confirmBox.append(h("div", { class: "actions" }, yes, no));
  ask.addEventListener("click", () => {
    confirmBox.hidden = false;
    ask.disabled = true;
  });
  no.addEventListener("click", () => {
    confirmBox.hidden = true;
    ask.disabled = false;
  });
  yes.addEventListener("click", async () => {
    yes.disabled = true;
    no.disabled = true;
    outcome.replaceChildren(h("p", { class: "muted" }, "Deploying…"));
    try {
      const d = await json(subject.deployments, { method: "POST", body: {} });
      outcome.replaceChildren(h("p", { class: "summary accepted", role: "status" }, `Verified: ${d.target} holds version ${d.version} (read back within ${d.deviation_mm.toFixed(4)} mm, ${d.deviation_deg.toFixed(4)} deg).`),
        ...(d.scope === "live" ? [h("p", { id: "deploy-live", class: "muted" }, LIVE_SCOPE)] : []));
    } catch (error) {
      const noWriter = error instanceof Problem && String(error.doc.type || "").endsWith("/no-frame-writer");
      outcome.replaceChildren(noWriter ? noWriterBox(error) : deployProblem(error));
    }
    confirmBox.hidden = true;
    await onChange(outcome);
  });
  box.append(ask, confirmBox, outcome);
  return box;
}

// A frame's controller section (the frame page): the state found at the last look (the fleet's
// frame row), the Deploy button as a tool's, and the frame's deployments, newest first.
async function frameControllerSection(frame, onChange) {
  const section = h("section", { id: "controller" }, h("h2", {}, "Controller"));
  const connection = await controllerOf(frame.robot_id);
  if (!connection) {
    section.append(h("p", { id: "controller-none" }, "This robot has no controller connection: an admin connects it (on its tools' pages or with tcpcal connect) to deploy and watch its frames."));
    return section;
  }
  const [rows, deployments] = await Promise.all([
    everyPage(`/v1/frames?robot_id=${frame.robot_id}`),
    everyPage(`/v1/frames/${frame.id}/deployments`),
  ]);
  const state = rows.find((r) => r.id === frame.id)?.controller ?? null;
  section.append(controllerStateLine(connection, state, frame.active_version));
  if (connection.scope === "live") section.append(h("p", { id: "controller-scope", class: "muted" }, LIVE_SCOPE));
  if (mayCalibrate()) section.append(deployControls(frameSubject(frame), connection, onChange));
  section.append(
    h("h3", {}, "Deployments"),
    deploymentsTable(deployments, []),
  );
  return section;
}

// ---- the controller connection (admin) -------------------------------------------------------
// The protocols and their default ports, read from the API's own schema (/openapi.json: the
// enum of ControllerIn's `protocol` and its `x-default-ports`), never a second list here.
let connectionSchema = null;
async function controllerProtocols() {
  if (!connectionSchema) {
    const response = await fetch("/openapi.json", { headers: { Accept: "application/json" } });
    if (!response.ok) throw new Error(`the API's schema (/openapi.json) answered ${response.status}`);
    const fields = (await response.json()).components.schemas.ControllerIn.properties;
    const protocol = fields.protocol;
    // The user field's hint is the schema's own description (which protocol takes a user).
    connectionSchema = { protocols: protocol.enum, defaults: protocol["x-default-ports"] ?? {}, userHint: fields.username?.description };
  }
  return connectionSchema;
}

// A field of the form: its label, the input, and where a 422 naming it is said.
function connectionField(label, input, hint) {
  return h("label", { class: "connection-field", "data-field": input.name },
    h("span", {}, label), input, hint ? h("span", { class: "muted hint" }, hint) : null,
    h("span", { class: "field-problem", role: "alert", hidden: true }));
}

// The body a PUT sends: what the person filled in; an empty field is left out (the server's
// default, and the stored password kept). A number field sends what was typed when it is not
// a number, so that the server's 422 names it.
function connectionBody(form, services) {
  const value = (name) => form.elements.namedItem(name)?.value.trim() ?? "";
  const number = (text) => (/^-?\d+(\.\d+)?$/.test(text) ? Number(text) : text);
  const body = { protocol: value("protocol"), host: value("host") };
  if (services) {
    const ports = {};
    for (const service of services) if (value(`ports.${service}`)) ports[service] = number(value(`ports.${service}`));
    if (Object.keys(ports).length) body.ports = ports;
  } else if (value("port")) body.port = number(value("port"));
  if (value("username")) body.username = value("username");
  // null removes the stored password (left out, it is kept)
  if (form.elements.namedItem("forget_password")?.checked) body.password = null;
  else if (form.elements.namedItem("password").value) body.password = form.elements.namedItem("password").value;
  if (value("timeout_s")) body.timeout_s = number(value("timeout_s"));
  return body;
}

// The field a 422 error's `loc` names (body.ports.rtde -> the rtde port; a `port` or `ports`
// as a whole -> the first port field), or null.
function connectionFieldFor(form, loc) {
  const parts = (loc || []).filter((part) => part !== "body").map(String);
  const fields = [...form.querySelectorAll(".connection-field")];
  for (let n = parts.length; n > 0; n -= 1) {
    const found = fields.find((f) => f.dataset.field === parts.slice(0, n).join("."));
    if (found) return found;
  }
  if (parts[0] === "port" || parts[0] === "ports") return fields.find((f) => f.dataset.field === "port" || f.dataset.field.startsWith("ports.")) ?? null;
  return null;
}

// Each 422 error said next to the field it names; what names no field goes under the form.
function showConnectionProblem(form, outcome, error) {
  const errors = error instanceof Problem && error.status === 422 ? (error.doc.errors || []) : [];
  let placed = 0;
  for (const e of errors) {
    const field = connectionFieldFor(form, e.loc);
    if (!field) continue;
    const said = field.querySelector(".field-problem");
    said.textContent = errors.length === 1 ? error.doc.detail : `${(e.loc || []).filter((p) => p !== "body").join(".")}: ${e.msg}`;
    said.hidden = false;
    placed += 1;
  }
  outcome.replaceChildren(placed && placed === errors.length
    ? h("p", { class: "muted", id: "connection-refused" }, `${error.status} ${error.doc.title || ""}: nothing was stored.`)
    : problemBox(error));
}

// The form's fields drawn once the API's schema is read; the page is not held up by it (a
// robot with a connection shows the form folded, and reads the schema when it is opened).
function connectionForm(tool, connection, onChange) {
  const details = h("details", { id: "connection", open: !connection },
    h("summary", {}, connection ? "Change the connection (admin)" : "Connect the controller (admin)"));
  let drawn = false;
  const draw = async () => {
    if (drawn) return;
    drawn = true;
    try {
      details.append(connectionFields(tool, connection, onChange, await controllerProtocols()));
    } catch (error) {
      details.append(problemBox(error));
    }
  };
  details.addEventListener("toggle", () => { if (details.open) draw(); });
  if (!connection) draw();
  return details;
}

function connectionFields(tool, connection, onChange, { protocols, defaults, userHint }) {
  const protocolSelect = h("select", { name: "protocol", id: "connection-protocol" },
    protocols.map((p) => h("option", { value: p, selected: connection?.protocol === p }, p)));
  const portsBox = h("div", { id: "connection-ports", class: "pose-fields" });
  const servicesOf = (protocol) => {
    const ports = defaults[protocol] ?? {};
    return "port" in ports ? null : Object.keys(ports);
  };
  const drawPorts = () => {
    const protocol = protocolSelect.value;
    const ports = defaults[protocol] ?? {};
    const services = servicesOf(protocol);
    const same = connection?.protocol === protocol;
    portsBox.replaceChildren(...(services
      ? services.map((service) => connectionField(`${service} port`,
        h("input", { name: `ports.${service}`, inputmode: "numeric", placeholder: String(ports[service]), value: same ? connection.ports?.[service] ?? "" : "" }),
        `default ${ports[service]}`))
      : [connectionField("port", h("input", { name: "port", inputmode: "numeric", placeholder: ports.port === undefined ? "" : String(ports.port), value: same ? connection.port ?? "" : "" }),
        ports.port === undefined ? null : `default ${ports.port}`)]));
  };
  protocolSelect.addEventListener("change", drawPorts);
  drawPorts();
  const outcome = h("div", { id: "connection-outcome" });
  const passwordInput = h("input", { name: "password", id: "connection-password", type: "password", autocomplete: "new-password" });
  const forgetPassword = h("input", { name: "forget_password", id: "connection-forget-password", type: "checkbox" });
  forgetPassword.addEventListener("change", () => {
    passwordInput.disabled = forgetPassword.checked;
    if (forgetPassword.checked) passwordInput.value = "";
  });
  const form = h("form", { id: "connection-form", class: "card" },
    connectionField("protocol", protocolSelect),
    connectionField("host", h("input", { name: "host", required: true, placeholder: "192.168.1.20", value: connection?.host ?? "" })),
    portsBox,
    connectionField("user", h("input", { name: "username", autocomplete: "off", value: connection?.username ?? "" }), userHint),
    connectionField("password", passwordInput,
      connection?.has_password ? "a password is stored: left empty, it is kept" : "write-only: never shown again"),
    connection?.has_password ? connectionField("remove the stored password", forgetPassword, "on save; the controller is then reached without one") : null,
    connectionField("timeout, s", h("input", { name: "timeout_s", inputmode: "decimal", placeholder: "5", value: connection ? connection.timeout_s : "" }), "default 5"),
    h("div", { class: "actions" }, h("button", { type: "submit", id: "connection-save" }, connection ? "Save connection" : "Connect")),
    outcome);
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    form.querySelectorAll(".field-problem").forEach((p) => { p.hidden = true; p.textContent = ""; });
    const save = form.querySelector("#connection-save");
    save.disabled = true;
    outcome.replaceChildren(h("p", { class: "muted" }, "Saving…"));
    try {
      await json(`/v1/robots/${tool.robot_id}/controller`, { method: "PUT", body: connectionBody(form, servicesOf(protocolSelect.value)) });
      await onChange();
    } catch (error) {
      showConnectionProblem(form, outcome, error);
      save.disabled = false;
    }
  });
  return form;
}

// ---- re-check after a collision (issue 41) ---------------------------------------------------
// The robot stands with the TCP at a reference point: one touch read from the controller checks
// the active TCP and, within the tool's max_correction_mm, corrects it (a new version, active,
// deployed and read back). The server does all of it (POST /v1/tools/{id}/checks, the service
// the CLI and the MQTT command use); the page asks first, with a reason, and says the answer.
// A correction changes the versions, so the page is drawn again and the answer kept above it.
let recheckAnswer = null; // { toolId, node } drawn into the next tool page of that tool

const VERDICT_LABELS = { within_tolerance: "In tolerance", out_of_tolerance: "Out of tolerance, not corrected", corrected: "Corrected", deployment_failed: "Corrected, deployment failed", recalibrate: "Recalibrate: nothing changed" };

function recheckAnswerNode(check, versions) {
  const c = check.correction;
  const lines = [];
  if (c) {
    const length = Math.hypot(...c.delta_mm);
    lines.push(
      h("dt", {}, "Version"), h("dd", { id: "recheck-version" }, `v${c.version} (was v${c.previous_version}), active`),
      h("dt", {}, "Moved by"), h("dd", { id: "recheck-delta" }, `${c.delta_mm.map((v) => `${v >= 0 ? "+" : ""}${v.toFixed(3)}`).join(", ")} mm (${length.toFixed(3)} mm, flange frame)`),
      h("dt", {}, "Deployment"), h("dd", { id: "recheck-deployment" }, c.deployment
        ? [deploymentBadge(c.deployment.status), " ", deploymentWords(c.deployment, versions), c.deployment.error ? ` (${c.deployment.error.detail})` : ""]
        : "not deployed: deploy it before the robot runs with it"),
    );
  }
  const good = check.verdict === "within_tolerance" || check.verdict === "corrected";
  return h("div", { class: "recheck-answer", "data-verdict": check.verdict, role: "status" },
    h("strong", {}, VERDICT_LABELS[check.verdict] ?? check.verdict),
    h("p", { class: `summary anywhere${good ? "" : " out_of_tolerance"}` }, check.summary),
    lines.length ? h("dl", { class: "correction" }, lines) : null);
}

function recheckControls(tool, points, versions) {
  const box = h("div", { id: "recheck" }, h("h3", {}, "Re-check after a collision"));
  const outcome = h("div", { id: "recheck-outcome" });
  if (recheckAnswer && recheckAnswer.toolId === tool.id) outcome.append(recheckAnswer.node);
  recheckAnswer = null;
  const select = h("select", { id: "recheck-point", name: "reference_point" },
    points.map((p) => h("option", { value: p.id }, `${p.name} (${vec(p.position_mm)} mm)`)));
  const correct = h("input", { type: "checkbox", id: "recheck-correct", name: "correct", checked: true });
  const limit = tool.tolerance.max_correction_mm ?? 2;
  const ask = h("button", { type: "button", id: "recheck-button" }, "Re-check");
  ask.addEventListener("click", () => {
    const point = points.find((p) => p.id === select.value);
    confirmDialog({
      title: `Re-check ${tool.name} at ${point.name}?`,
      lines: [
        `The robot must stand still with the TCP at ${point.name}: its flange pose is read from the controller as the one touch.`,
        correct.checked
          ? `Off by more than check ${mm(tool.tolerance.check_mm)} mm and at most ${mm(limit)} mm, the TCP that touch gives becomes a new active version (orientation kept) and is deployed and read back. Further off, nothing changes.`
          : "Only measured: nothing changes whatever it finds.",
      ],
      confirm: "Re-check now",
      onConfirm: async (reason) => {
        ask.disabled = true;
        outcome.replaceChildren(h("p", { class: "muted" }, "Reading the robot…"));
        const body = { capture: true, reference_point_id: point.id, correct: correct.checked ? "within_limits" : "never", reason };
        try {
          const check = await json(`/v1/tools/${tool.id}/checks`, { method: "POST", body });
          recheckAnswer = { toolId: tool.id, node: recheckAnswerNode(check, versions) };
          await route();
        } catch (error) {
          outcome.replaceChildren(problemBox(error));
          ask.disabled = false;
        }
      },
    });
  });
  box.append(
    h("p", { class: "actions" },
      h("label", { for: "recheck-point" }, "Reference point "), select, " ",
      h("label", {}, correct, ` correct within ${mm(limit)} mm and deploy`), " ", ask),
    outcome);
  return box;
}

// ---- confirmation -----------------------------------------------------------------------------
// A modal that says what will change and asks why (1-500 characters, kept in the history).
function confirmDialog({ title, lines, confirm, onConfirm }) {
  const reason = h("textarea", { name: "reason", rows: 3, maxlength: 500, required: true, placeholder: "why (kept in the tool's history and audit trail)" });
  const dialog = h(
    "dialog",
    { id: "confirm", "aria-labelledby": "confirm-title" },
    h("form", { method: "dialog" },
      h("h2", { id: "confirm-title" }, title),
      lines.filter(Boolean).map((line) => h("p", {}, line)),
      h("label", { for: "confirm-reason" }, "Reason"),
      reason,
      h("div", { class: "actions" },
        h("button", { type: "submit", value: "confirm", class: "primary" }, confirm),
        h("button", { type: "button", value: "cancel", onclick: () => dialog.close("cancel") }, "Cancel"))),
  );
  reason.id = "confirm-reason";
  dialog.addEventListener("close", () => {
    const text = reason.value.trim();
    dialog.remove();
    if (dialog.returnValue === "confirm" && text) onConfirm(text);
  });
  dialog.querySelector("form").addEventListener("submit", (event) => {
    if (!reason.value.trim()) {
      event.preventDefault();
      reason.setCustomValidity("Give a reason");
      reason.reportValidity();
    }
  });
  reason.addEventListener("input", () => reason.setCustomValidity(""));
  document.body.append(dialog);
  dialog.showModal();
  reason.focus();
}

// ---- plots ----------------------------------------------------------------------------------
// Plotly (3.5 MB, the installed plotly package's own copy) is loaded by the pages that plot, once
// per tab, as they start fetching their data: the fleet page and the sign-in never wait for it
// (parsing it took 2.4-2.8 s of CPU per page load on a slow 2-core machine).
const PLOTLY_URL = "/ui/vendor/plotly.min.js";
let plotlyLoading = null;
function plotly() {
  plotlyLoading ??= new Promise((resolve, reject) => {
    const script = h("script", { src: PLOTLY_URL });
    script.addEventListener("load", () => resolve(window.Plotly));
    script.addEventListener("error", () => {
      plotlyLoading = null; // the next page tries again
      reject(new Error(`could not load ${PLOTLY_URL}: the plots are not drawn`));
    });
    document.head.append(script);
  });
  return plotlyLoading;
}

// Each plot's height, written once: its div is drawn at it with the page and Plotly draws at it.
// A responsive plot's container is 100 % of a div whose height is its min-height, so narrowing
// the window let the residual chart's 300 px hang 58 px out of its 242 px div; and a div given
// its height only when Plotly had loaded (seconds on a slow tablet) pushed everything below it
// down by 240 px, under a finger already on its way to a button (the tool page's Activate).
const PLOT_HEIGHT = { "plot-tcp": 480, "plot-checks": 280, "plot-residuals": 300, "plot-3d": 520, "frame-plot": 420 };
function plotBox(id, attrs = {}) {
  const box = h("div", { id, class: "plot", ...attrs });
  box.style.minHeight = `${PLOT_HEIGHT[id]}px`;
  return box;
}
function newPlot(id, traces, layout, config) {
  return Plotly.newPlot(id, traces, { ...layout, height: PLOT_HEIGHT[id] }, config);
}

// Draws a page's plots once Plotly is loaded; a page without plots never loads it. If it cannot
// be loaded, each plot's box says so and the rest of the page stays.
async function withPlotly(draw) {
  if (!main.querySelector(".plot")) return;
  try {
    await plotly();
  } catch (error) {
    for (const box of main.querySelectorAll(".plot")) box.replaceChildren(h("p", { class: "muted" }, error.message));
    return;
  }
  draw();
}

// ---- tool -----------------------------------------------------------------------------------
// The versions a rollback can return to, the active one last: the server's rule
// (rollback_stack in app/services/tools/activation.py) replayed over GET .../versions' activations,
// oldest first. Each activation moves its version to the top; a rollback first takes off the
// version it left. Roll back is offered only when something lies below the top (it was offered
// always, and a tool activated once got "409 Nothing to roll back" after giving a reason).
function rollbackStack(activations) {
  const stack = [];
  for (const a of activations) {
    if (a.reason === "rollback" && stack.length) stack.pop();
    if (stack.includes(a.version)) stack.splice(stack.indexOf(a.version), 1);
    stack.push(a.version);
  }
  return stack;
}

async function toolPage(toolId) {
  const toolResponse = await api(`/v1/tools/${toolId}`);
  const etag = toolResponse.headers.get("ETag");
  const tool = await toolResponse.json();
  document.title = `${tool.name} · tcpcal`;
  const [robot, versions, calibrations, checks, formats, drift] = await Promise.all([
    json(`/v1/robots/${tool.robot_id}`),
    json(`/v1/tools/${toolId}/versions`),
    everyPage(`/v1/tools/${toolId}/calibrations`),
    everyPage(`/v1/tools/${toolId}/checks`),
    json("/v1/formats"),
    json(`/v1/tools/${toolId}/drift`),
  ]);
  const sigmaOf = new Map(calibrations.filter((c) => c.version !== null).map((c) => [c.version, c.quality.tcp_sigma_mm]));

  const calibrationOf = new Map(calibrations.filter((c) => c.version !== null).map((c) => [c.version, c]));
  // Every write is sent with the ETag the page was drawn from: a stale page changes nothing.
  // What went wrong is drawn under the row (or beside the button) that was clicked.
  const send = async (path, body, button) => {
    try {
      await api(path, { method: "POST", body, headers: { "If-Match": etag } });
      route();
    } catch (error) {
      if (error instanceof Problem && error.status === 412) {
        noteBeside(button,
          h("div", { class: "problem", role: "alert" },
            h("strong", {}, "Not changed: this page is out of date."),
            h("p", {}, "The tool changed since this page was loaded (another activation or a new calibration). Nothing was changed. Reload to see the current versions, then decide again."),
            h("button", { type: "button", onclick: () => route() }, "Reload")),
        );
      } else noteBeside(button, problemBox(error));
    }
  };
  const activate = (v, button) => {
    const outOfTolerance = v.status === "out_of_tolerance";
    const cal = calibrationOf.get(v.version);
    confirmDialog({
      title: `Activate version ${v.version} of ${tool.name}?`,
      lines: [
        `Controllers reading this tool will get TCP ${vec(v.tcp.position_mm)} mm instead of ${tool.active_version === null ? "nothing" : `version ${tool.active_version}`}.`,
        outOfTolerance
          ? h("span", { class: "warning" }, `Version ${v.version} is stored as out of tolerance${cal ? ` (${cal.summary}; worst touch ${mm(cal.quality.max_mm)} mm)` : ""}. It goes live only with your reason, sent with force.`)
          : null,
      ],
      confirm: outOfTolerance ? "Activate anyway" : "Activate",
      onConfirm: (reason) => send(`/v1/tools/${toolId}/versions/${v.version}/activate`, outOfTolerance ? { reason, force: true } : { reason }, button),
    });
  };
  const stack = rollbackStack(versions.activations);
  const rollbackTo = tool.active_version !== null && stack.length >= 2 ? stack[stack.length - 2] : null;
  const rollBack = (event) => {
    const button = event.currentTarget;
    confirmDialog({
      title: `Roll back ${tool.name} to version ${rollbackTo}?`,
      lines: [`Version ${tool.active_version} stops being served; version ${rollbackTo}, the one active before it (from the activation history), goes live again.`],
      confirm: "Roll back",
      onConfirm: (reason) => send(`/v1/tools/${toolId}/rollback`, { reason }, button),
    });
  };
  const writes = mayCalibrate();

  const versionRows = versions.items.slice().reverse().map((v) =>
    h(
      "tr",
      { class: v.active ? "active" : null, "data-version": v.version },
      h("td", { class: "num" }, v.version),
      h("td", {}, badge(v.status)),
      h("td", { class: "num" }, vec(v.tcp.position_mm)),
      h("td", {}, v.source),
      h("td", { class: "anywhere" }, v.note ?? ""),
      h("td", {}, v.created_by),
      h("td", {}, when(v.created_at)),
      h("td", {}, v.calibration_id ? h("a", { href: `/ui/calibrations/${v.calibration_id}` }, "report") : "—"),
      h("td", {}, v.active ? h("strong", {}, "active")
        : writes ? h("button", { type: "button", class: "activate", onclick: (event) => activate(v, event.currentTarget) }, "Activate") : null),
    ),
  );
  const activationRows = versions.activations.slice().reverse().map((a) =>
    h("tr", {}, h("td", {}, when(a.activated_at)), h("td", { class: "num" }, a.version), h("td", { class: "num" }, a.previous_version ?? "—"), h("td", {}, a.reason), h("td", { class: "reason-text anywhere" }, a.reason_text ?? ""), h("td", {}, a.activated_by)),
  );

  const controllerBox = h("div", { id: "controllers", class: "grid" });
  const controllerSlot = h("div", { id: "controller-slot" });
  // After a deployment the section is drawn again (its state and history), keeping the outcome.
  const drawController = async (outcome) => {
    const section = await controllerSection(tool, versions.items, drawController);
    if (outcome) section.querySelector("#deploy-outcome")?.replaceWith(outcome);
    controllerSlot.replaceChildren(section);
  };
  // Both sections above the versions are filled before the page is shown: drawn after it, they
  // pushed the versions table down under a finger (or a click) already on its way to a button.
  await Promise.all([drawController(null), tool.active_version === null ? null : fillControllers(tool, formats, controllerBox)]);
  show(
    h("h1", {}, `${tool.name} `, h("span", { class: "muted" }, `on ${robot.name}`)),
    writes ? h("p", {}, h("a", { id: "calibrate-link", class: "button-link", href: `/ui/tools/${tool.id}/calibrate` }, "Calibrate at the cell")) : null,
    h("p", {}, `Cell ${robot.cell ?? "—"} · slot ${tool.slot ?? "—"} · active version ${tool.active_version ?? "none"} · tolerance rms ${mm(tool.tolerance.max_rms_mm)} mm, residual ${mm(tool.tolerance.max_residual_mm)} mm, check ${mm(tool.tolerance.check_mm)} mm`),
    controllerSlot,
    h("section", {}, h("h2", {}, "Active TCP for the controllers"), tool.active_version === null ? h("p", {}, "No active TCP: calibrate or activate a version.") : controllerBox),
    h("section", {}, h("h2", {}, "TCP over the versions"), versions.items.length ? plotBox("plot-tcp") : h("p", { id: "no-versions" }, "No versions yet: calibrate the tool, or enter its TCP by hand (method manual)."),
      driftLine("drift-versions", drift.versions, "calibrated versions")),
    h("section", {}, h("h2", {}, "Checks over time"), checks.length ? plotBox("plot-checks") : h("p", {}, "No checks recorded yet."),
      driftLine("drift-checks", drift.checks, "checks of the active version")),
    h("section", {}, h("h2", {}, "Versions"),
      writes && rollbackTo !== null ? h("p", {}, h("button", { type: "button", id: "rollback", onclick: rollBack }, `Roll back to version ${rollbackTo}`)) : null,
      writes && tool.active_version !== null && rollbackTo === null
        ? h("p", { id: "no-rollback", class: "muted" }, `Nothing to roll back to: no version was active before version ${tool.active_version}, or rollbacks have gone back through each one.`) : null,
      h("table", { id: "versions" }, h("thead", {}, h("tr", {}, ["Version", "Status", "TCP x, y, z mm", "Source", "Why", "By", "When", "", ""].map((c) => h("th", {}, c)))), h("tbody", {}, versionRows))),
    h("section", {}, h("h2", {}, "Activation history"),
      h("table", { id: "activations" }, h("thead", {}, h("tr", {}, ["When", "Version", "Previous", "Kind", "Reason", "By"].map((c) => h("th", {}, c)))), h("tbody", {}, activationRows))),
    await auditSection(toolId),
  );

  await withPlotly(() => {
    if (versions.items.length) plotTcp(versions.items, sigmaOf);
    if (checks.length) plotChecks(checks, tool.tolerance.check_mm, drift.checks);
  });
}

// ---- the audit trail (admin keys) ------------------------------------------------------------
function auditWhy(event) {
  const d = event.detail || {};
  if ("reason" in d) return d.previous_version === null || d.previous_version === undefined ? d.reason : `${d.reason} (was v${d.previous_version})`;
  if (Array.isArray(d.changed)) {
    const from = d.from || {}, to = d.to || {};
    return d.changed.flatMap((field) => {
      if (!(field in to)) return [field];
      if (to[field] && typeof to[field] === "object" && from[field] && typeof from[field] === "object") {
        return Object.keys(to[field]).filter((k) => from[field][k] !== to[field][k]).map((k) => `${field}.${k} ${from[field][k]} → ${to[field][k]}`);
      }
      return [`${field} ${from[field]} → ${to[field]}`];
    }).join("; ");
  }
  if (event.action === "calibration.create") return `${d.method} ${d.status}${d.note ? `: ${d.note}` : ""}`;
  if (d.summary) return d.summary;
  return Object.entries(d).filter(([, v]) => v === null || typeof v !== "object").map(([k, v]) => `${k} ${v}`).join(", ");
}

async function auditSection(toolId) {
  const heading = h("h2", {}, "Audit trail");
  let events;
  try {
    events = (await json(`/v1/audit?tool_id=${encodeURIComponent(toolId)}&limit=200`)).items;
  } catch (error) {
    if (error instanceof Problem && error.status === 403) {
      return h("section", {}, heading, h("p", { id: "audit-needs-admin", class: "muted" }, "The audit trail (who changed what, when and why) needs an admin key: sign in with one to see it."));
    }
    return h("section", {}, heading, problemBox(error));
  }
  const rows = events.map((e) =>
    h("tr", { "data-action": e.action },
      h("td", {}, when(e.at)), h("td", {}, e.actor), h("td", {}, e.action),
      h("td", { class: "num" }, e.version ?? "—"), h("td", { class: "anywhere" }, auditWhy(e)),
      h("td", { class: "muted anywhere" }, e.request_id ?? "")),
  );
  return h("section", {}, heading,
    events.length
      ? h("table", { id: "audit" }, h("thead", {}, h("tr", {}, ["When", "Who", "What", "Version", "Why", "Request"].map((c) => h("th", {}, c)))), h("tbody", {}, rows))
      : h("p", {}, "No changes recorded for this tool."));
}

// A controller line may wrap after a comma as well as at a space (a script's set_tcp(p[...])
// has no space in 80 characters and ran out of its card); <wbr> adds no character to a selection.
const wrapAfterCommas = (text) => text.split(/(?<=,)/).flatMap((part, i) => (i ? [h("wbr"), part] : [part]));

// A card's file download. A format whose file addresses the tool by its number (its maker
// declares tool_numbers, served as /v1/formats' tool_numbers) has no file for a tool without a slot: the button is
// off and says why (it did nothing when clicked). Any refusal on a click is shown in the card.
function downloadButton(tool, name, kind, numbers) {
  const label = `Download ${kind}`;
  if (numbers && tool.slot === null) {
    const why = `Set the tool's slot (${numbers[0]}-${numbers[1]} on ${name.toUpperCase()}) to download its ${kind}: the file addresses the tool by its number, and this tool has none.`;
    return [h("button", { type: "button", class: "download", disabled: true, title: why }, label), h("p", { class: "unavailable muted" }, why)];
  }
  const save = h("button", { type: "button", class: "download", title: `the ${kind} the controller loads, with a header naming the version` }, label);
  save.addEventListener("click", () => {
    save.closest(".card").querySelector(".problem")?.remove();
    download(`/v1/tools/${tool.id}/tcp?format=${name}`, "text/plain", `${name}.txt`)
      .catch((error) => save.closest(".card").append(problemBox(error)));
  });
  return [save];
}

async function fillControllers(tool, formats, box) {
  const files = formats.controller_files || {};
  const numbered = formats.tool_numbers || {};
  const cards = await Promise.all(formats.controllers.map(async (name) => {
    let doc;
    try {
      doc = await json(`/v1/tools/${tool.id}/tcp?format=${name}`);
    } catch (error) {
      if (!(error instanceof Problem)) throw error;
      return h("div", { class: "card", "data-format": name }, h("h3", {}, name), h("p", { class: "muted" }, error.message));
    }
    const text = doc.controller.text;
    const copy = h("button", { type: "button", class: "copy" }, "Copy");
    copy.addEventListener("click", () => copyText(text, copy));
    const [save, why] = downloadButton(tool, name, files[name] || "file", numbered[name]);
    return h("div", { class: "card", "data-format": name }, h("h3", {}, name), h("pre", {}, wrapAfterCommas(text)), h("div", { class: "actions" }, copy, save), why);
  }));
  box.replaceChildren(...cards);
}

// A time axis over at least two days: with one point (or points made minutes apart) Plotly
// zooms to a sub-millisecond span, and a limit line drawn from the first to the last point
// has no length at all.
const DAY_MS = 86400000;
function timeRange(isoDates) {
  const times = isoDates.map((iso) => new Date(iso).getTime());
  const first = Math.min(...times);
  const last = Math.max(...times);
  const pad = last - first < 2 * DAY_MS ? DAY_MS : (last - first) * 0.05;
  return [new Date(first - pad).toISOString(), new Date(last + pad).toISOString()];
}

// One step per version, in order, labelled v1, v2, ...: on a time axis versions made minutes
// apart piled up into one point (the page's plot read as a single version). When each was
// made is in the hover; the versions table and the drift line below carry the times.
const MAX_VERSION_TICKS = 24;
function plotTcp(versions, sigmaOf) {
  const steps = versions.map((_, i) => i + 1);
  const every = Math.ceil(versions.length / MAX_VERSION_TICKS);
  const ticks = steps.filter((step) => (step - 1) % every === 0 || step === versions.length);
  const axes = ["x", "y", "z"];
  const traces = axes.map((axis, i) => ({
    type: "scatter",
    mode: "lines+markers",
    name: `${axis} mm`,
    x: steps,
    y: versions.map((v) => v.tcp.position_mm[i]),
    customdata: versions.map((v) => [`v${v.version}`, when(v.created_at)]),
    hovertemplate: `%{customdata[0]} · %{customdata[1]}<br>${axis} %{y:.3f} mm<extra></extra>`,
    error_y: { type: "data", array: versions.map((v) => sigmaOf.get(v.version)?.[i] ?? 0), visible: true },
    xaxis: "x",
    yaxis: `y${i === 0 ? "" : i + 1}`,
  }));
  newPlot("plot-tcp", traces, {
    grid: { rows: 3, columns: 1, shared_xaxes: true },
    xaxis: { type: "linear", range: [0.5, versions.length + 0.5], tickmode: "array", tickvals: ticks, ticktext: ticks.map((step) => `v${versions[step - 1].version}`), zeroline: false },
    margin: { t: 10, r: 10, b: 40, l: 70 },
    yaxis: { title: { text: "x mm" }, tickformat: ".3f", ...spanAtLeast(traces[0]) },
    yaxis2: { title: { text: "y mm" }, tickformat: ".3f", ...spanAtLeast(traces[1]) },
    yaxis3: { title: { text: "z mm" }, tickformat: ".3f", ...spanAtLeast(traces[2]) },
    showlegend: false,
  }, { displaylogo: false, responsive: true });
}

// An axis shown to 3 decimals spans at least MIN_SPAN_MM: one version with a 1-sigma of
// thousandths (or none) autoranged to a few thousandths, and every tick read "12.500".
const MIN_SPAN_MM = 0.02;
function spanAtLeast(trace) {
  const errors = trace.error_y.array;
  const low = Math.min(...trace.y.map((y, i) => y - errors[i]));
  const high = Math.max(...trace.y.map((y, i) => y + errors[i]));
  if (high - low >= MIN_SPAN_MM) return {};
  const middle = (low + high) / 2;
  return { range: [middle - MIN_SPAN_MM / 2, middle + MIN_SPAN_MM / 2] };
}

// A series' drift under its plot: the rate ± its standard error with the 95 % interval per
// axis, and when the projection leaves check_mm; tinted when that is within 30 days.
function driftLine(id, trend, what) {
  if (!trend) return h("p", { id, class: "drift muted" }, `Drift: no trend yet (it needs three ${what} over a day or more).`);
  const axes = ["x", "y", "z"].map((a, i) => `${a} ${trend.rate_mm_per_month[i].toFixed(3)} [${trend.low_mm_per_month[i].toFixed(3)}, ${trend.high_mm_per_month[i].toFixed(3)}]`).join(", ");
  const crosses = trend.crosses_check_at;
  const soon = crosses !== null && new Date(crosses).getTime() <= Date.now() + 30 * DAY_MS;
  return h("p", { id, class: `drift${soon ? " attention" : ""}` },
    h("strong", { class: "rate" }, `Drift ${rate(trend.speed_mm_per_month, trend.speed_sigma_mm_per_month)}`),
    ` over ${trend.n} ${what} (per axis, 95 % interval: ${axes})`,
    crosses ? `; projected out of check_mm by ${when(crosses)} at 95 % confidence.` : "; not projected out of check_mm within two years.");
}

// The checks' trend as a distance over time: |level + rate (t - t0)| from the first check to
// 30 days past the last (or to where it leaves check_mm, when sooner).
function trendTrace(trend) {
  const start = new Date(trend.first_at).getTime();
  const end = new Date(trend.last_at).getTime() + 30 * DAY_MS;
  const t0 = new Date(trend.t0_at).getTime();
  const xs = Array.from({ length: 50 }, (_, i) => start + ((end - start) * i) / 49);
  const distance = (t) => Math.hypot(...trend.level_mm.map((l, i) => l + trend.rate_mm_per_month[i] * (t - t0) / (30.44 * DAY_MS)));
  return { type: "scatter", mode: "lines", name: "trend", x: xs.map((t) => new Date(t).toISOString()), y: xs.map(distance), line: { dash: "dot", color: "#6a1b9a" } };
}

function plotChecks(checks, limit, trend) {
  const ordered = checks.slice().reverse();
  const trace = trend ? trendTrace(trend) : null;
  const range = timeRange([...ordered.map((c) => c.checked_at), ...(trace ? [trace.x[trace.x.length - 1]] : [])]);
  const top = 1.15 * Math.max(limit, ...ordered.map((c) => c.distance_mm), ...(trace ? trace.y : []));
  newPlot("plot-checks", [
    { type: "scatter", mode: "lines+markers", name: "distance mm", x: ordered.map((c) => c.checked_at), y: ordered.map((c) => c.distance_mm),
      marker: { color: ordered.map((c) => (c.within_tolerance ? "#2e7d32" : "#c62828")), size: 10 } },
    { type: "scatter", mode: "lines", name: "check_mm", x: range, y: [limit, limit], line: { dash: "dash", color: "#c62828" } },
    ...(trace ? [trace] : []),
  ], { margin: { t: 10, r: 10, b: 40, l: 70 }, xaxis: { type: "date", range }, yaxis: { title: { text: "distance mm" }, range: [0, top] } }, { displaylogo: false, responsive: true });
}

// ---- calibration report ---------------------------------------------------------------------
async function reportPage(calibrationId) {
  const cal = await json(`/v1/calibrations/${calibrationId}`);
  const tool = await json(`/v1/tools/${cal.tool_id}`);
  document.title = `Report ${tool.name} v${cal.version ?? "-"} · tcpcal`;
  const q = cal.quality;
  const geometry = cal.geometry;
  const row = (label, value, field) => h("tr", {}, h("th", {}, label), h("td", { class: "num", "data-field": field }, value));
  const figures = h(
    "table",
    { id: "figures", class: "figures" },
    h("tbody", {},
      row("TCP position x, y, z (mm)", vec(cal.tcp.position_mm), "tcp_mm"),
      row("TCP orientation (w, x, y, z)", cal.tcp.quaternion.map((v) => v.toFixed(6)).join(", "), "quaternion"),
      row("rms residual (mm)", mm(q.rms_mm), "rms_mm"),
      row("max residual (mm)", mm(q.max_mm), "max_mm"),
      row("1-sigma x, y, z (mm)", vec(q.tcp_sigma_mm), "tcp_sigma_mm"),
      row("95 % ellipsoid semi-axes (mm)", geometry?.ellipsoid95_semi_axes_mm ? vec(geometry.ellipsoid95_semi_axes_mm) : "—", "ellipsoid95"),
      row("touched point x, y, z (mm)", vec(cal.reference_point_mm), "point_mm"),
      row("touches", q.n_poses, "n_poses"),
      row("outliers (touch numbers)", q.outliers.length ? q.outliers.map((i) => i + 1).join(", ") : "none", "outliers"),
      row("orientation spread (deg)", q.orientation_spread_deg === null ? "—" : q.orientation_spread_deg.toFixed(1), "spread"),
      row("change from active (mm)", mm(cal.change_from_active_mm), "change_mm"),
      row("method", `${cal.method}${cal.algorithm ? ` (${cal.algorithm})` : ""}`, "method"),
      row("version", `${cal.version ?? "—"}${cal.active ? " (active)" : ""}`, "version"),
      row("by, when", `${cal.created_by}, ${when(cal.created_at)}`, "created"),
    ),
  );
  show(
    h("div", { class: "report-head" },
      h("h1", {}, `Calibration report: ${tool.name}`),
      h("button", { type: "button", class: "no-print", onclick: () => window.print() }, "Print")),
    h("p", { class: "muted" }, h("a", { href: `/ui/tools/${tool.id}` }, `${tool.name}`), ` · calibration ${cal.id}`),
    h("p", { id: "summary", class: `summary ${cal.status}` }, cal.summary),
    cal.warnings.length ? h("section", {}, h("h2", {}, "Warnings"), h("ul", { id: "warnings" }, cal.warnings.map((w) => h("li", {}, w)))) : null,
    h("section", {}, h("h2", {}, "Figures"), figures),
    q.residuals_mm.length ? h("section", { class: "plot-section" }, h("h2", {}, "Residual per touch"), plotBox("plot-residuals")) : null,
    geometry ? h("section", { class: "plot-section" }, h("h2", {}, "Touches in space (base frame, mm)"), plotBox("plot-3d")) : null,
    h("section", {}, h("h2", {}, "Request as received"), h("pre", { id: "raw-request", class: "raw" }, JSON.stringify(cal.request, null, 2))),
  );
  await withPlotly(() => {
    if (q.residuals_mm.length) plotResiduals(q, tool.tolerance);
    if (geometry) plot3d(cal, geometry);
  });
}

function plotResiduals(q, tolerance) {
  const outliers = new Set(q.outliers);
  const n = q.residuals_mm.length;
  const touch = q.residuals_mm.map((_, i) => i + 1);
  newPlot("plot-residuals", [
    { type: "bar", name: "residual mm", x: touch, y: q.residuals_mm,
      marker: { color: q.residuals_mm.map((_, i) => (outliers.has(i) ? "#c62828" : "#1565c0")) },
      text: q.residuals_mm.map((v, i) => (outliers.has(i) ? `${mm(v)} outlier` : mm(v))), textposition: "outside",
      hovertemplate: "touch %{x}: %{y:.3f} mm<extra></extra>" },
    { type: "scatter", mode: "lines", name: "max_residual_mm", x: [0.5, n + 0.5], y: [tolerance.max_residual_mm, tolerance.max_residual_mm], line: { dash: "dash", color: "#c62828" } },
  ], { margin: { t: 20, r: 10, b: 40, l: 70 }, xaxis: { title: { text: "touch" }, tickmode: "linear", dtick: 1 }, yaxis: { title: { text: "mm" }, rangemode: "tozero" }, showlegend: false }, { displaylogo: false, responsive: true, staticPlot: false });
}

function plot3d(cal, geometry) {
  const outliers = new Set(cal.quality.outliers);
  const flanges = geometry.flange_positions_mm;
  const tips = geometry.tip_positions_mm;
  const label = flanges.map((_, i) => `touch ${i + 1}${outliers.has(i) ? " (outlier)" : ""}`);
  const col = (points, i) => points.map((p) => p[i]);
  const shafts = { x: [], y: [], z: [] };
  flanges.forEach((f, i) => {
    for (const [k, axis] of ["x", "y", "z"].entries()) shafts[axis].push(f[k], tips[i][k], null);
  });
  const traces = [
    { type: "scatter3d", mode: "lines", name: "tool (flange to TCP)", ...shafts, line: { color: "#90a4ae", width: 3 }, hoverinfo: "skip" },
    { type: "scatter3d", mode: "markers+text", name: "flange", x: col(flanges, 0), y: col(flanges, 1), z: col(flanges, 2), text: flanges.map((_, i) => String(i + 1)),
      marker: { size: 4, color: flanges.map((_, i) => (outliers.has(i) ? "#c62828" : "#1565c0")) }, hovertext: label },
    { type: "scatter3d", mode: "markers", name: "TCP at each touch", x: col(tips, 0), y: col(tips, 1), z: col(tips, 2),
      marker: { size: 3, color: tips.map((_, i) => (outliers.has(i) ? "#c62828" : "#2e7d32")) }, hovertext: label },
  ];
  if (cal.reference_point_mm) {
    const [x, y, z] = cal.reference_point_mm;
    traces.push({ type: "scatter3d", mode: "markers", name: "touched point", x: [x], y: [y], z: [z], marker: { size: 6, symbol: "diamond", color: "#ff8f00" } });
  }
  newPlot("plot-3d", traces, { margin: { t: 0, r: 0, b: 0, l: 0 }, scene: { aspectmode: "data" }, legend: { x: 0, y: 1 } }, { displaylogo: false, responsive: true });
}

// The helpers the calibrate page (calibrate.js) draws and talks to the API with.
const pageHelpers = () => ({ h, show, api, json, everyPage, Problem, problemBox, confirmDialog, deployProblem, frameControllerSection, mm, vec, when, mayCalibrate, plot, plotBox });

// A plot of a page that draws as it goes (the frame page): Plotly loaded first.
async function plot(id, traces, layout) {
  await withPlotly(() => newPlot(id, traces, layout, { displaylogo: false, responsive: true }));
}

// ---- routing --------------------------------------------------------------------------------
// main is aria-busy while a page is fetched and drawn: assistive technology waits for the
// whole page, and so do the browser tests before they click (a plot drawn late moves buttons).
async function route() {
  const path = window.location.pathname;
  const tool = path.match(/^\/ui\/tools\/([^/]+)$/);
  const report = path.match(/^\/ui\/calibrations\/([^/]+)$/);
  const calibrate = path.match(/^\/ui\/tools\/([^/]+)\/calibrate$/);
  const teach = path.match(/^\/ui\/frames\/([^/]+)\/calibrate$/);
  // A page that plots fetches Plotly at once (while its key is typed, beside its data); it
  // awaits it, and shows its error, where it plots.
  if (tool || report || teach) plotly().catch(() => {});
  if (!sessionStorage.getItem(KEY_STORE)) return signIn(route);
  main.setAttribute("aria-busy", "true");
  document.getElementById("sign-out").hidden = false;
  try {
    if (me === null) me = await json("/v1/keys/me");
    document.getElementById("who").textContent = `${me.name} (${me.scope})`;
    if (tool) await toolPage(decodeURIComponent(tool[1]));
    else if (calibrate) await calibratePage(decodeURIComponent(calibrate[1]), pageHelpers());
    else if (teach) await frameCalibratePage(decodeURIComponent(teach[1]), pageHelpers());
    else if (report) await reportPage(decodeURIComponent(report[1]));
    else await fleetPage();
  } catch (error) {
    if (error instanceof Problem && error.status === 401) return signIn(route, "Your key is no longer accepted; sign in again.");
    show(h("h1", {}, "Could not load this page"), problemBox(error), h("p", {}, h("a", { href: "/ui/" }, "Back to the fleet")));
  } finally {
    main.setAttribute("aria-busy", "false");
  }
}

document.getElementById("sign-out").addEventListener("click", () => {
  sessionStorage.removeItem(KEY_STORE);
  me = null;
  document.getElementById("who").textContent = "";
  signIn(route);
});

route();
