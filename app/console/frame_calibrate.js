// The frame page, /ui/frames/{id}/calibrate (API.md v1.4 "Sessions:"): a guided frame session at
// the cell, on a tablet and by keyboard alone. The next touch is the server's words (next_role,
// with how far it must be); the method is chosen among GET /v1/methods' frame methods of the
// frame's kind that take touches; each touch is captured from the robot's controller or typed,
// sent with the role the server names next (fit_points: with its point in the frame, typed in
// the nominal field, as GET /v1/methods' touch_fields asks), and each can be deleted before
// Finish (DELETE /v1/sessions/{id}/poses/{index}); a 3-D picture shows the touched points and,
// once the touches give one, the frame's axes. Finish shows the stored frame, its sigmas and
// summary. main is aria-busy while a touch is sent and drawn (as console.js's pages).
// Re-check after a move (API.md v1.4 "After a move: re-register"): the same guided session with
// "method": "recheck", each stored fiducial touched again (captured or typed, sent as the
// fiducial the server names next), finished as the frame's check; the page says each
// fiducial's deviation, the shift, and what became of the frame (corrected to vN and deployed,
// or nothing changed). GET /v1/methods lists calibration methods; recheck is a session method
// of a check, named by the contract, not one of them.
// console.js passes its helpers in `ui` (one definition each).

const AXIS_MM = 150; // length of each drawn axis
const HTTP_CALL = / ?\((?:GET|POST|PUT|PATCH|DELETE) \/[^)]*\)/g;
const AXES = [["X", "#d62728"], ["Y", "#2ca02c"], ["Z", "#1f77b4"]];

// The frame's axis k (a unit column of its rotation) from its quaternion [w, x, y, z].
function axis(q, k) {
  const [w, x, y, z] = q;
  return [
    [1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)],
    [2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)],
    [2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)],
  ][k];
}

export async function frameCalibratePage(frameId, ui) {
  const { h, show, json, problemBox } = ui;
  const frame = await json(`/v1/frames/${frameId}`);
  document.title = `Teach ${frame.name} · tcpcal`;
  const [robot, tools, methods] = await Promise.all([
    json(`/v1/robots/${frame.robot_id}`),
    json(`/v1/robots/${frame.robot_id}/tools?limit=200`),
    json("/v1/methods"),
  ]);
  // The frame methods of the frame's kind that take touches, as the server lists them (no
  // copy here); the first is the default.
  const choices = methods.frame_methods.filter((m) => m.kinds.includes(frame.kind) && m.max_touches > 0);
  const body = h("div", { id: "frame-calibrate" });
  // The frame's controller state and Deploy (console.js, as a tool's), drawn again after a
  // deployment (keeping its outcome) and after Finish (a new active version).
  const controllerSlot = h("div", { id: "controller-slot" });
  const drawController = async (outcome) => {
    const current = await json(`/v1/frames/${frameId}`);
    const section = await ui.frameControllerSection(current, drawController);
    if (outcome) section.querySelector("#deploy-outcome")?.replaceWith(outcome);
    controllerSlot.replaceChildren(section);
  };
  show(h("h1", {}, `Teach ${frame.name} `, h("span", { class: "muted" }, `(${frame.kind}) on ${robot.name}`)), controllerSlot, body);
  await drawController();
  if (!ui.mayCalibrate()) {
    body.append(h("p", { class: "problem" }, "Teaching a frame needs a key of calibrate scope: sign in with one."));
    return;
  }
  const method = h("select", { name: "method", "aria-label": "method" },
    ...choices.map((m) => h("option", { value: m.name, title: m.description }, m.name)));
  const pointer = h("select", { name: "pointer", "aria-label": "pointer tool" },
    ...tools.items.map((t) => h("option", { value: t.id }, t.name)));
  const format = h("input", { name: "format", value: robot.pose_format ?? "kuka_abc", "aria-label": "pose format" });
  const problem = h("div", { id: "frame-problem" });
  const start = h("form", { id: "frame-start", onsubmit: async (event) => {
    event.preventDefault();
    problem.replaceChildren();
    try {
      const session = await json(`/v1/frames/${frame.id}/sessions`, { method: "POST", body: { method: method.value, tool_id: pointer.value, format: format.value } });
      const chosen = choices.find((m) => m.name === method.value);
      drawSession(ui, body, frame, session, drawController, TEACH, "nominal_mm" in (chosen?.touch_fields ?? {}));
    } catch (error) {
      problem.replaceChildren(problemBox(error));
    }
  } }, h("label", {}, "Method ", method), " ", h("label", {}, "Pointer tool ", pointer), " ", h("label", {}, "Pose format ", format), " ",
  h("button", { type: "submit" }, "Start teaching"));
  body.replaceChildren(start, problem, await recheckStart(ui, body, frame, tools, robot, drawController));
}

// The re-check's options (as POST /v1/frames/{id}/checks takes them) and its start; none when
// the frame keeps no fiducials to touch again.
async function recheckStart(ui, body, frame, tools, robot, drawController) {
  const { h, json, problemBox } = ui;
  const box = h("section", { id: "recheck-frame" }, h("h2", {}, "Re-check after a move"));
  let fiducials = [];
  try {
    fiducials = (await json(`/v1/frames/${frame.id}/fiducials`)).items;
  } catch (error) {
    box.append(problemBox(error));
    return box;
  }
  if (!fiducials.length) {
    box.append(h("p", { class: "muted" }, "This frame keeps no fiducials to touch again: calibrate it from touches first."));
    return box;
  }
  const pointer = h("select", { name: "recheck-pointer", "aria-label": "re-check pointer tool" },
    ...tools.items.map((t) => h("option", { value: t.id }, t.name)));
  const format = h("input", { name: "recheck-format", value: robot.pose_format ?? "kuka_abc", "aria-label": "re-check pose format" });
  const correct = h("input", { type: "checkbox", name: "correct", checked: true });
  const whole = h("input", { type: "checkbox", name: "scope-robot" });
  const reason = h("input", { name: "reason", "aria-label": "reason", placeholder: "why (kept in the history)", maxlength: "500" });
  const problem = h("div", { id: "recheck-problem" });
  const limits = frame.tolerance ?? {};
  const form = h("form", { id: "recheck-start", onsubmit: async (event) => {
    event.preventDefault();
    problem.replaceChildren();
    const options = { correct: correct.checked ? "within_limits" : "never", scope: whole.checked ? "robot" : "frame" };
    if (reason.value.trim()) options.reason = reason.value.trim();
    try {
      const session = await json(`/v1/frames/${frame.id}/sessions`, { method: "POST", body: { method: "recheck", tool_id: pointer.value, format: format.value, options } });
      drawSession(ui, body, frame, session, drawController, RECHECK);
    } catch (error) {
      problem.replaceChildren(problemBox(error));
    }
  } },
  h("p", {}, `Touch its stored fiducials again (at least 3 of ${fiducials.map((f) => f.name).join(", ")}): the shift they moved by is found and, when asked, the frame corrected.`),
  h("p", {}, h("label", {}, "Pointer tool ", pointer), " ", h("label", {}, "Pose format ", format)),
  h("p", {}, h("label", {}, correct, ` correct it within ${limits.max_correction_mm ?? "its"} mm and deploy`), " ",
    h("label", {}, whole, " the robot moved: correct every frame and reference point of it")),
  h("p", {}, h("label", {}, "Reason ", reason), " ", h("button", { type: "submit" }, "Start re-check")));
  box.append(form, problem);
  return box;
}

// What a session's touches name and how it is finished and said: a calibration's roles, or a
// re-check's fiducials.
const TEACH = {
  key: "role",
  done: "Done: finish to store the frame.",
  finishBody: { activate: "auto" },
  result: calibrationResult,
};
const RECHECK = {
  key: "fiducial",
  done: "Every fiducial touched: finish to check the frame.",
  finishBody: {},
  result: checkResult,
};

function calibrationResult(ui, cal) {
  const { h } = ui;
  const q = cal.quality;
  return [
    h("h2", {}, `Frame v${cal.version}: ${cal.status}`),
    h("p", { id: "frame-origin" }, `Origin ${cal.frame.position_mm.map((v) => v.toFixed(3)).join("  ")} mm, quaternion ${cal.frame.quaternion.map((v) => v.toFixed(6)).join("  ")}`),
    h("p", { id: "frame-sigmas" }, `1-sigma: position ${(q.position_sigma_mm ?? []).map((v) => v.toFixed(3)).join("  ")} mm, angle ${(q.angle_sigma_deg ?? []).map((v) => v.toFixed(4)).join("  ")} deg`),
    h("p", { id: "frame-summary" }, cal.summary),
  ];
}

// mm to 3 decimals with its sign, a value that rounds to nothing as +0.000 (never -0.000).
function signed(v) {
  const text = (Math.abs(v) < 0.0005 ? 0 : v).toFixed(3);
  return text.startsWith("-") ? text : `+${text}`;
}

// A frame check in words: what became of the frame, each fiducial's deviation, the shift.
function checkResult(ui, check) {
  const { h } = ui;
  const c = check.correction;
  const d = c?.deployment;
  let outcome;
  if (c) {
    const deployed = !d ? "not deployed (the summary says why)"
      : d.status === "verified" ? `deployed to ${d.target} and read back as written (verified)`
        : `its deployment ${d.status.replace("_", " ")}: ${d.error?.detail ?? "see the deployments"}`;
    outcome = `Corrected to v${c.version} (was v${c.previous_version}), active; ${deployed}`;
  } else if (check.verdict === "within_tolerance") {
    outcome = `Within tolerance at v${check.version}: nothing changed`;
  } else {
    outcome = `Not corrected: nothing changed (v${check.version} stays active)`;
  }
  const s = check.shift;
  const moved = Math.hypot(...s.position_mm);
  return [
    h("h2", { id: "check-outcome", "data-verdict": check.verdict }, outcome),
    h("ul", { id: "check-deviations" }, ...check.deviations.map((dev) => h("li", {}, dev.words))),
    h("p", { id: "check-shift" }, `Shift: ${s.position_mm.map(signed).join("  ")} mm (${moved.toFixed(3)} mm) and ${s.angle_deg.toFixed(3)} deg about ${s.axis.map((v) => v.toFixed(3)).join("  ")}`),
    ...(c?.moved?.length ? [h("p", { id: "check-moved" }, `Also corrected by the same shift: ${c.moved.map((m) => `${m.name} v${m.version ?? "?"}`).join(", ")}`)] : []),
    h("p", { id: "frame-summary" }, check.summary.replace(HTTP_CALL, "")),
  ];
}

function drawSession(ui, body, frame, session, drawController, kind = TEACH, takesNominal = false) {
  const { h, json, problemBox, mm } = ui;
  const next = h("p", { id: "next-role", class: "next", role: "status" });
  const touches = h("ol", { id: "frame-touches" });
  const problem = h("div", { id: "frame-problem" });
  const result = h("section", { id: "frame-result" });
  const plotBox = ui.plotBox("frame-plot", { role: "img", "aria-label": "touched points and the frame's axes" });
  const typed = h("input", { name: "pose", "aria-label": "typed pose", placeholder: `a pose in ${session.format}` });
  // fit_points: the next touch's point in the frame (mm, from the fixture's drawing), sent as
  // its nominal_mm with a captured or a typed pose.
  const nominal = takesNominal
    ? h("input", { name: "nominal", id: "nominal", inputmode: "decimal", autocomplete: "off", "aria-label": "the touch's point in the frame: x y z mm", placeholder: "x y z mm in the frame" })
    : null;
  const main = document.querySelector("main");
  let state = session;
  // One change of the session (a touch added or deleted) at a time, main aria-busy until it is
  // drawn. A touch names the role the session asked for last: sent while the one before it was
  // on its way, it went in that one's role (two +X touches for an Enter pressed twice, and no
  // XY touch), so the touch buttons are off until the change is drawn and a second is not sent.
  let busy = false;
  let finished = false;
  const change = async (call) => {
    if (busy) return false;
    busy = true;
    problem.replaceChildren();
    main.setAttribute("aria-busy", "true");
    for (const button of touchButtons()) button.disabled = true;
    try {
      state = await call();
      redraw();
      return true;
    } catch (error) {
      problem.replaceChildren(problemBox(error));
      return false;
    } finally {
      busy = false;
      for (const button of touchButtons()) button.disabled = finished;
      main.setAttribute("aria-busy", "false");
    }
  };
  const send = async (touch) => {
    if (busy) return false;
    if (state.next?.role) touch[kind.key] = state.next.role;
    if (nominal) {
      const xyz = nominal.value.trim().split(/[\s,]+/).filter((v) => v !== "").map(Number);
      if (xyz.length !== 3 || xyz.some((v) => !Number.isFinite(v))) {
        problem.replaceChildren(h("p", { class: "problem", role: "alert" }, "Give this touch's point in the frame first: three numbers, x y z in mm (the fixture's drawing)."));
        nominal.focus();
        return false;
      }
      touch.nominal_mm = xyz;
    }
    const sent = await change(() => json(`/v1/sessions/${state.id}/poses`, { method: "POST", body: touch }));
    if (sent && nominal) nominal.value = "";
    return sent;
  };
  // focus returns to where the next touch starts
  const remove = async (index) => {
    await change(() => json(`/v1/sessions/${state.id}/poses/${index}`, { method: "DELETE" }));
    (nominal ?? capture).focus();
  };
  const capture = h("button", { id: "capture", type: "button", onclick: async () => {
    if (await send({ capture: true })) (nominal ?? capture).focus();
  } }, "Capture");
  const typeForm = h("form", { id: "type-touch", onsubmit: async (event) => {
    event.preventDefault();
    const pose = typed.value.trim().split(/[\s,]+/).map(Number);
    if (await send({ pose })) typed.value = "";
  } }, typed, " ", h("button", { type: "submit" }, "Add typed touch"));
  const touchButtons = () => [capture, typeForm.querySelector("button[type=submit]"), ...touches.querySelectorAll("button.delete")];
  const finish = h("button", { id: "finish", type: "button", onclick: async () => {
    problem.replaceChildren();
    try {
      const done = await json(`/v1/sessions/${state.id}/finish`, { method: "POST", body: kind.finishBody });
      result.replaceChildren(...kind.result(ui, done));
      finished = true;
      for (const button of touchButtons()) button.disabled = true;
      finish.disabled = true;
      result.focus();
      await drawController();
    } catch (error) {
      problem.replaceChildren(problemBox(error));
    }
  } }, "Finish");
  result.setAttribute("tabindex", "-1");
  const redraw = () => {
    next.textContent = state.next_role ? `Next: ${state.next_role}${state.done && kind === RECHECK ? " (or finish: enough fiducials touched)" : ""}` : state.done ? kind.done : "";
    touches.replaceChildren(...state.touches.map((t, i) => h("li", {},
      `${t[kind.key] ?? t.role ?? (t.nominal_mm ? `at ${t.nominal_mm.join(" ")}` : "touch")} (${t.source}): ${t.point_mm ? t.point_mm.map((v) => v.toFixed(3)).join("  ") + " mm" : "no point: the pointer has no TCP"} `,
      h("button", { type: "button", class: "delete", "aria-label": `Delete touch ${i + 1}`, onclick: () => remove(i) }, "Delete"))));
    // the server's words, less the HTTP call it names for an API client: the buttons say it here
    for (const message of state.messages) touches.append(h("li", { class: "muted" }, message.replace(HTTP_CALL, "")));
    ui.plot("frame-plot", traces(state), { margin: { l: 0, r: 0, t: 0, b: 0 }, scene: { aspectmode: "data" }, showlegend: true });
  };
  const nominalField = nominal ? [h("label", {}, "Point in the frame (mm) ", nominal), " "] : [];
  body.replaceChildren(next, h("div", { class: "actions" }, ...nominalField, capture, " ", typeForm, " ", finish), problem, touches, plotBox, result);
  redraw();
  (nominal ?? capture).focus();
}

// The touched points, and the frame's axes from its origin once the touches give a frame.
function traces(state) {
  const points = state.touches.filter((t) => t.point_mm);
  const out = [{
    type: "scatter3d", mode: "markers+text", name: "touches",
    x: points.map((t) => t.point_mm[0]), y: points.map((t) => t.point_mm[1]), z: points.map((t) => t.point_mm[2]),
    text: points.map((t) => t.role ?? ""), marker: { size: 5 },
  }];
  const estimate = state.estimate;
  if (estimate) {
    const o = estimate.position_mm;
    AXES.forEach(([name, color], k) => {
      const a = axis(estimate.quaternion, k);
      out.push({ type: "scatter3d", mode: "lines", name: `frame ${name}`, line: { color, width: 6 },
        x: [o[0], o[0] + AXIS_MM * a[0]], y: [o[1], o[1] + AXIS_MM * a[1]], z: [o[2], o[2] + AXIS_MM * a[2]] });
    });
  }
  return out;
}
