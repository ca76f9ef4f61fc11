// The calibrate page, /ui/tools/{id}/calibrate (contract v1.3): a guided xyz_npoint session at
// the cell, on a tablet (768 px and up) and by keyboard alone. Every figure comes from the
// session as the server computes it on each read (estimate, 1-sigma, residuals, outliers, the
// next pose and its tilt and spin from the first touch): the page parses no pose itself.
// console.js passes its helpers in `ui` (one definition each).

// The pose format a robot's pendant shows, as the server says: its controller's (by its
// protocol), else its maker's (by its vendor), else the first format listed (GET /v1/formats).
export function robotFormat(robot, connection, formats) {
  return connection?.pose_format ?? robot.pose_format ?? formats[0];
}

// "2.000" for a length, "45.0" for an angle: what a pendant shows.
function figure(value, component, units) {
  const angle = /^(a|b|c|w|p|r|rx|ry|rz|q\d+)$/i.test(component);
  if (units && !angle && units.length === "m") return Number(value).toFixed(6);
  if (angle && units && units.angle === "rad") return Number(value).toFixed(5);
  return Number(value).toFixed(3);
}

// A pose as the pendant shows it, one part a number: ["X 812.000", "Y …", …]; a matrix is its
// four rows.
function poseParts(pose, info, units) {
  if (Array.isArray(pose[0])) return pose.map((row) => row.map((v) => Number(v).toFixed(4)).join("  "));
  const names = info?.components ?? pose.map((_, i) => `q${i + 1}`);
  return pose.map((v, i) => `${names[i] ?? `q${i + 1}`} ${figure(v, names[i] ?? "", units)}`);
}
const poseText = (pose, info, units) => poseParts(pose, info, units).join(Array.isArray(pose[0]) ? "\n" : "  ");

// The nearest of the eight directions in the first touch's flange x-y plane.
const LEANS = ["+x", "+x +y", "+y", "−x +y", "−x", "−x −y", "−y", "+x −y"];
const leanWords = (deg) => LEANS[Math.round(deg / 45) % 8];
const signed = (deg) => `${deg >= 0 ? "+" : "−"}${Math.abs(deg).toFixed(1)}°`;

export function touchInWords(next) {
  if (!next) return "";
  const tilt = next.tilt_deg < 0.05 ? "keep the tool axis as at touch 1" : `tilt the tool axis ${next.tilt_deg.toFixed(1)}° from touch 1's, leaning toward touch 1's flange ${leanWords(next.lean_deg)} (${next.lean_deg.toFixed(0)}° from +x)`;
  const spin = Math.abs(next.spin_deg) < 0.05 ? "no spin about it" : `spin ${signed(next.spin_deg)} about the tool axis`;
  return `From touch 1: ${tilt}, ${spin}; then touch the point.`;
}

export async function calibratePage(toolId, ui) {
  const { h, show, json, everyPage, Problem } = ui;
  const tool = await json(`/v1/tools/${toolId}`);
  document.title = `Calibrate ${tool.name} · tcpcal`;
  const [robot, formats, methods, sessions] = await Promise.all([
    json(`/v1/robots/${tool.robot_id}`),
    json("/v1/formats"),
    json("/v1/methods"),
    json(`/v1/tools/${toolId}/sessions?limit=20`),
  ]);
  let connection = null;
  try {
    connection = await json(`/v1/robots/${tool.robot_id}/controller`);
  } catch (error) {
    if (!(error instanceof Problem) || !String(error.doc.type || "").endsWith("/no-controller")) throw error;
  }
  const infoOf = new Map(formats.items.map((f) => [f.name, f]));
  // The method a guided session collects touches for, as the server says (no copy here).
  const guided = methods.items.find((m) => m.guided).name;
  const page = { tool, robot, connection, infoOf, guided, ui, everyPage };
  const header = [
    h("h1", {}, `Calibrate ${tool.name} `, h("span", { class: "muted" }, `on ${robot.name}`)),
    h("p", { class: "muted" }, h("a", { href: `/ui/tools/${tool.id}` }, `Back to ${tool.name}`),
      ` · touch one fixed point from several orientations; each touch is ${connection ? `captured from the ${connection.protocol} controller at ${connection.host} or typed` : "typed as the pendant shows it"}.`),
  ];
  const open = sessions.items.find((s) => s.status === "open");
  const body = h("div", { id: "calibrate" });
  show(...header, body);
  if (!ui.mayCalibrate()) {
    body.append(h("p", { id: "needs-calibrate", class: "problem" }, "Calibrating needs a key of calibrate scope: sign in with one."));
    return;
  }
  if (open) drawSession(page, body, open, { resumed: true });
  else drawStart(page, body);
}

function drawStart(page, body) {
  const { h, json, problemBox } = page.ui;
  const fallback = robotFormat(page.robot, page.connection, [...page.infoOf.keys()]);
  const select = h("select", { id: "session-format", name: "format" },
    [...page.infoOf.keys()].filter((name) => name !== "joints").map((name) => h("option", { value: name, selected: name === fallback }, name)));
  const outcome = h("div", { id: "start-outcome" });
  const form = h("form", { id: "start-session", class: "card" },
    h("h2", {}, "Start a session"),
    h("p", {}, "The session suggests each next touch and says when the TCP is known well enough. Poses are in the robot's own format; change it only if the pendant shows another."),
    h("label", {}, "Pose format ", select),
    h("div", { class: "actions" }, h("button", { type: "submit", id: "start", class: "primary" }, "Start")),
    outcome);
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    try {
      const session = await json(`/v1/tools/${page.tool.id}/sessions`, { method: "POST", body: { method: page.guided, format: select.value } });
      drawSession(page, body, session, { resumed: false });
    } catch (error) {
      outcome.replaceChildren(problemBox(error));
    }
  });
  body.replaceChildren(form);
  form.querySelector("#start").focus();
}

// A refused touch, said so a person at the robot knows what to do next.
function touchProblem(page, error) {
  const { h, problemBox, Problem } = page.ui;
  const type = error instanceof Problem ? String(error.doc.type || "") : "";
  if (type.endsWith("/robot-moving")) {
    return h("div", { class: "problem", role: "alert", id: "touch-problem", "data-type": "robot-moving" },
      h("strong", {}, "The robot was moving: nothing was kept."),
      h("p", {}, "A capture reads the pose twice, 100 ms apart, and keeps it only if the two agree within 0.01 mm and 0.01°. Let the robot come to rest at the touch (release the jog keys, wait a moment), then press Capture again."),
      h("p", { class: "muted anywhere" }, error.doc.detail || ""));
  }
  const box = problemBox(error);
  box.id = "touch-problem";
  return box;
}

function drawSession(page, body, session, { resumed }) {
  const { h, json, problemBox } = page.ui;
  const info = page.infoOf.get(session.format);
  const status = h("div", { id: "touch-status", role: "status" });
  const progress = h("div", { id: "progress" });
  let busy = false;

  const apply = (next) => {
    session = next;
    status.replaceChildren();
    progress.replaceChildren(...sessionView(page, session, remove));
    finish.disabled = session.n_poses < 4; // a calibration needs 4 touches
  };
  const send = async (what, request, focusAfter) => {
    if (busy) return;
    busy = true;
    body.setAttribute("aria-busy", "true");
    status.replaceChildren(h("p", { class: "muted" }, what));
    try {
      apply(await request());
    } catch (error) {
      status.replaceChildren(touchProblem(page, error));
    } finally {
      busy = false;
      body.setAttribute("aria-busy", "false");
      focusAfter?.focus();
    }
  };
  const remove = (index) => send(`Deleting touch ${index + 1}…`,
    () => json(`/v1/sessions/${session.id}/poses/${index}`, { method: "DELETE" }), capture ?? inputs[0]);

  const capture = page.connection
    ? h("button", { type: "button", id: "capture", class: "primary big" }, "Capture")
    : null;
  capture?.addEventListener("click", () => send("Reading the pose from the controller (two reads 100 ms apart)…",
    () => json(`/v1/sessions/${session.id}/poses`, { method: "POST", body: { capture: true } }), capture));

  // The typed pose: one field per number of the format, in the pendant's order.
  const flat = info && info.arity !== null && info.components.length <= 7;
  const inputs = flat
    ? info.components.map((name) => h("input", { name, id: `pose-${name}`, inputmode: "decimal", autocomplete: "off", required: true, class: "pose-number", "aria-label": name }))
    : [h("input", { name: "pose", id: "pose-text", autocomplete: "off", required: true, class: "pose-text", "aria-label": "pose: 16 numbers, row by row" })];
  const typed = h("form", { id: "typed-touch", class: "typed" },
    h("fieldset", {},
      h("legend", {}, `Or type the pose (${session.format}${info ? `, ${info.default_units.length}, ${info.default_units.angle}` : ""})`),
      h("div", { class: "pose-fields" }, (flat ? info.components : ["pose"]).map((name, i) => h("label", {}, h("span", {}, name), inputs[i]))),
      h("button", { type: "submit", id: "add-typed" }, "Add touch")));
  typed.addEventListener("submit", (event) => {
    event.preventDefault();
    const numbers = flat ? inputs.map((input) => Number(input.value.trim().replace(",", ".")))
      : inputs[0].value.split(/[\s,;]+/).filter(Boolean).map(Number);
    if (numbers.some((v) => !Number.isFinite(v))) {
      status.replaceChildren(h("p", { class: "problem", role: "alert", id: "touch-problem" }, "Each field takes one number (a decimal point or comma)."));
      return;
    }
    const pose = flat ? numbers : [0, 4, 8, 12].map((i) => numbers.slice(i, i + 4));
    send("Adding the typed touch…", async () => {
      const next = await json(`/v1/sessions/${session.id}/poses`, { method: "POST", body: { pose } });
      inputs.forEach((input) => (input.value = ""));
      return next;
    }, inputs[0]);
  });
  // Pasting a whole pose (six numbers from a pendant's screen) into the first field fills all.
  inputs[0].addEventListener("paste", (event) => {
    if (!flat) return;
    const numbers = (event.clipboardData?.getData("text") || "").match(/-?\d+(?:[.,]\d+)?(?:e-?\d+)?/gi) || [];
    if (numbers.length !== inputs.length) return;
    event.preventDefault();
    numbers.forEach((n, i) => (inputs[i].value = n.replace(",", ".")));
  });

  const finishOutcome = h("div", { id: "finish-outcome" });
  const finish = h("button", { type: "button", id: "finish", class: "primary" }, "Finish");
  finish.addEventListener("click", async () => {
    finish.disabled = true;
    try {
      const cal = await json(`/v1/sessions/${session.id}/finish`, { method: "POST", body: { activate: "never" } });
      drawReport(page, body, cal);
    } catch (error) {
      finishOutcome.replaceChildren(problemBox(error));
      finish.disabled = false;
    }
  });

  body.replaceChildren(...[
    resumed ? h("p", { id: "resumed", class: "muted" }, `Resumed the open session started ${page.ui.when(session.created_at)} (${session.n_poses} ${session.n_poses === 1 ? "touch" : "touches"} so far).`) : null,
    h("section", { id: "touch-input", class: "card" },
      h("h2", {}, "Touch the point"),
      capture ? h("div", { class: "capture-row" }, capture, h("span", { class: "muted" }, `reads the flange from ${page.connection.host} when the robot stands still at the touch`)) : h("p", { id: "no-capture", class: "muted" }, "This robot has no controller connection: type each touch as the pendant shows it."),
      typed,
      status),
    progress,
    h("section", { id: "finish-section" }, h("p", { class: "muted" }, "Finish stores the touches as a calibration (4 or more) and shows its report; you activate it and deploy it from there."), finish, finishOutcome),
  ].filter(Boolean));
  apply(session);
  (capture ?? inputs[0]).focus();
}

// The session as the server computed it: the next touch (in the robot's format and in
// words), done, the estimate with its 1-sigma, then every touch with its residual.
function sessionView(page, session, remove) {
  const { h, mm, vec, when } = page.ui;
  const info = page.infoOf.get(session.format);
  const units = session.units ?? info?.default_units;
  const outliers = new Set(session.outliers);
  const residuals = session.residuals_mm;
  const nodes = [];
  if (session.done) {
    nodes.push(h("p", { id: "done", class: "summary accepted", role: "status" }, `Done: the TCP is known to ${mm(Math.max(...session.estimate.tcp_sigma_mm))} mm (1 sigma, largest axis), within the target ${session.target_sigma_mm} mm. Finish to store it.`));
  } else if (session.next_pose) {
    nodes.push(h("section", { id: "next-touch", class: "card next" },
      h("h2", {}, `Next: touch ${session.n_poses + 1}`),
      h("p", { id: "next-words", class: "words" }, touchInWords(session.next_touch)),
      h("pre", { id: "next-pose", class: "pose" }, poseText(session.next_pose, info, units)),
      h("p", { class: "muted" }, `${session.format}: the flange pose that puts the current TCP estimate on the point; jog until the tip touches it.`)));
  } else if (session.n_poses === 0) {
    nodes.push(h("section", { id: "next-touch", class: "card next" }, h("h2", {}, "Touch 1"), h("p", { id: "next-words" }, "Touch the point with the tool in a comfortable orientation: the next touches are suggested from this one.")));
  }
  const e = session.estimate;
  nodes.push(h("section", { id: "estimate" }, h("h2", {}, "Estimate"),
    e ? h("table", { class: "figures" }, h("tbody", {},
      h("tr", {}, h("th", {}, "TCP x, y, z (mm)"), h("td", { class: "num", "data-field": "tcp_mm" }, vec(e.tcp_mm))),
      h("tr", {}, h("th", {}, "1-sigma x, y, z (mm)"), h("td", { class: "num", "data-field": "tcp_sigma_mm" }, `± ${vec(e.tcp_sigma_mm)}`)),
      h("tr", {}, h("th", {}, "rms residual (mm)"), h("td", { class: "num", "data-field": "rms_mm" }, mm(e.rms_mm))),
      h("tr", {}, h("th", {}, "target 1-sigma (mm)"), h("td", { class: "num" }, mm(session.target_sigma_mm)))))
      : h("p", { id: "no-estimate", class: "muted" }, `No estimate yet: it needs 4 touches (${session.n_poses} so far).`)));
  if (session.messages.length) nodes.push(h("ul", { id: "messages" }, session.messages.map((m) => h("li", {}, m))));
  const rows = session.poses.map((pose, i) => {
    const source = session.touches[i];
    const out = outliers.has(i);
    return h("tr", { class: out ? "outlier" : null, "data-index": i, "data-source": source?.source ?? "typed" },
      h("td", { class: "num" }, i + 1),
      h("td", {}, source?.source === "controller" ? `captured ${source.read_at ? when(source.read_at) : ""}` : "typed"),
      h("td", { class: "pose" }, poseParts(pose, info, units).map((part) => h("span", { class: "part" }, part))),
      h("td", { class: "num residual" }, residuals ? mm(residuals[i]) : "—"),
      h("td", { class: "flag" }, out ? h("strong", { class: "badge out_of_tolerance" }, "outlier: touch again, delete this") : ""),
      h("td", {}, h("button", { type: "button", class: "delete", "aria-label": `Delete touch ${i + 1}`, onclick: () => remove(i) }, "Delete")));
  });
  nodes.push(h("section", { id: "touches-section" }, h("h2", {}, `Touches (${session.n_poses})`),
    h("table", { id: "touches" }, h("thead", {}, h("tr", {}, ["#", "Source", `Pose (${session.format})`, "Residual mm", "", ""].map((c) => h("th", {}, c)))), h("tbody", {}, rows))));
  return nodes;
}

// After Finish: the calibration's figures, a link to its full report, Activate, then Deploy.
function drawReport(page, body, cal) {
  const { h, mm, vec, json, problemBox, confirmDialog, deployProblem } = page.ui;
  const tool = page.tool;
  const outcome = h("div", { id: "after-outcome" });
  const actions = h("div", { class: "actions", id: "after-actions" });
  const deploy = page.connection ? h("button", { type: "button", id: "deploy-new", disabled: true }, `Deploy version ${cal.version}`) : null;
  const activate = cal.version === null ? null : h("button", { type: "button", id: "activate-new", class: "primary" }, `Activate version ${cal.version}`);
  const outOfTolerance = cal.status === "out_of_tolerance";
  activate?.addEventListener("click", () => confirmDialog({
    title: `Activate version ${cal.version} of ${tool.name}?`,
    lines: [
      `Controllers reading this tool will get TCP ${vec(cal.tcp.position_mm)} mm instead of ${tool.active_version === null ? "nothing" : `version ${tool.active_version}`}.`,
      outOfTolerance ? h("span", { class: "warning" }, `Version ${cal.version} is out of tolerance (${cal.summary}). It goes live only with your reason, sent with force.`) : null,
    ],
    confirm: outOfTolerance ? "Activate anyway" : "Activate",
    onConfirm: async (reason) => {
      try {
        await json(`/v1/tools/${tool.id}/versions/${cal.version}/activate`, { method: "POST", body: outOfTolerance ? { reason, force: true } : { reason } });
        outcome.replaceChildren(h("p", { class: "summary accepted", role: "status", id: "activated" }, `Version ${cal.version} is active.${deploy ? " Deploy it to write it into the controller." : ""}`));
        activate.disabled = true;
        if (deploy) {
          deploy.disabled = false;
          deploy.focus();
        }
      } catch (error) {
        outcome.replaceChildren(problemBox(error));
        activate.focus();
      }
    },
  }));
  deploy?.addEventListener("click", async () => {
    deploy.disabled = true;
    outcome.replaceChildren(h("p", { class: "muted" }, "Deploying…"));
    try {
      const d = await json(`/v1/tools/${tool.id}/deployments`, { method: "POST", body: {} });
      outcome.replaceChildren(h("p", { class: "summary accepted", role: "status", id: "deployed" }, `Verified: ${d.target} holds version ${d.version} (read back within ${d.deviation_mm.toFixed(4)} mm, ${d.deviation_deg.toFixed(4)} deg).`));
    } catch (error) {
      outcome.replaceChildren(deployProblem(error));
      deploy.disabled = false;
    }
  });
  if (activate) actions.append(activate);
  if (deploy) actions.append(deploy);
  const q = cal.quality;
  const row = (label, value, field) => h("tr", {}, h("th", {}, label), h("td", { class: "num", "data-field": field }, value));
  body.replaceChildren(h("section", { id: "finished", class: "card" },
    h("h2", {}, `Calibration ${cal.version === null ? "(not versioned)" : `version ${cal.version}`}`),
    h("p", { id: "finished-summary", class: `summary ${cal.status}` }, cal.summary),
    h("table", { class: "figures" }, h("tbody", {},
      row("TCP x, y, z (mm)", vec(cal.tcp.position_mm), "tcp_mm"),
      row("1-sigma x, y, z (mm)", vec(q.tcp_sigma_mm), "tcp_sigma_mm"),
      row("rms, max residual (mm)", `${mm(q.rms_mm)}, ${mm(q.max_mm)}`, "rms_mm"),
      row("touches", q.n_poses, "n_poses"),
      row("change from active (mm)", mm(cal.change_from_active_mm), "change_mm"))),
    h("p", {}, h("a", { id: "report-link", href: `/ui/calibrations/${cal.id}` }, "Full report"), " · ", h("a", { href: `/ui/tools/${tool.id}` }, `${tool.name}'s page`)),
    actions, outcome,
    h("p", {}, h("a", { href: `/ui/tools/${tool.id}/calibrate`, id: "calibrate-again" }, "Start another session"))));
  (activate ?? body.querySelector("#report-link")).focus();
}
