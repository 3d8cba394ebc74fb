// The operator console: scenario -> plan -> flight, on one page, through the public API.
import { ApiError, forgetToken, get, hasToken, post, token, wsUrl } from "./api.js";
import { AreaEditor } from "./area.js";
import { colourOf, FieldMap, positionAt } from "./field.js";

const $ = (id) => document.getElementById(id);
const FINAL_JOB = new Set(["done", "failed", "cancelled", "interrupted"]);
const FINAL_FLIGHT = new Set(["landed", "aborted", "ended", "cancelled"]);
const POLL_MS = 2000;
const EVENTS_SHOWN = 200; // the newest, in the events list
// The event kinds this page looks for: their wire names (gcs.fleet.events.EventKind).
const KIND = Object.freeze({
  PROGRESS: "Progress", ITEM_REACHED: "ItemReached", FLIGHT_ENDED: "FlightEnded",
  OBJECT_REPORTED: "ObjectReported", POSITIONS: "Positions",
});

const field = new FieldMap($("map"), document.querySelector('meta[name="tile-url"]').content);
const S = {
  scenario: null, scenarioId: null, dirty: false, selected: 0,
  plan: null, job: null, jobWs: null,
  flight: null, flightWs: null, live: null, replanned: new Set(),
  vehicles: [], discovered: [], reportMode: false,
  playing: false, t: 0, tMax: 0,
};
const area = new AreaEditor(field, {
  say: (...a) => say(...a), fail: (e) => fail(e), vehicles: () => S.vehicles,
  stored: (data) => {
    setScenario(data.scenario, data.id, true, data.geographic);
    loadStoredList().catch(fail);
    say(`area stored as ${data.id}: its grid is drawn; Plan when ready`);
  },
});
// Measured in the page (performance.now() milliseconds); the browser test reads them.
const timings = {};
window.consoleTimings = timings;

// --- small helpers -------------------------------------------------------------------

function say(text, kind = "info") {
  const box = $("status");
  box.textContent = text;
  box.className = kind;
}

function fail(error) {
  say(error instanceof ApiError ? `${error.status}: ${error.message}` : String(error), "error");
}

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "text") node.textContent = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) node.setAttribute(k, v === true ? "" : v);
  }
  node.append(...children);
  return node;
}

const fmt = (v, digits = 2) => (v == null || Number.isNaN(v) ? "–" : Number(v).toFixed(digits));

/** Every row of a list endpoint: they page oldest first (at most 200 rows a page). */
async function getAll(path, pages = 50) {
  const size = 200;
  const out = [];
  for (let k = 0; k < pages; k++) {
    const page = await get(`${path}?limit=${size}&offset=${k * size}`);
    out.push(...page);
    if (page.length < size) break;
  }
  return out;
}

/** Every stored event of a flight, oldest first, page by page after the last id seen: a
 * long or large flight stores more than one page holds. */
async function allEvents(flightId) {
  const size = 10000;
  const out = [];
  for (;;) {
    const after = out.length ? out[out.length - 1].id : 0;
    const page = await get(`/flights/${flightId}/events?after=${after}&limit=${size}`);
    out.push(...page);
    if (page.length < size) return out;
  }
}

function order(uavId) {
  const uavs = S.scenario?.uavs ?? S.plan?.plan.uavs ?? [];
  const i = uavs.findIndex((u) => u.id === uavId);
  return i < 0 ? 0 : i;
}

function radii() {
  return new Map((S.scenario?.uavs ?? []).map((u) => [u.id, u.radius ?? 0.3]));
}

// --- validation errors next to the field they name ---------------------------------------

function clearErrors(container) {
  container.querySelectorAll(".field-error").forEach((n) => n.remove());
  container.querySelectorAll("[aria-invalid]").forEach((n) => n.removeAttribute("aria-invalid"));
  const box = container.querySelector(".field-errors");
  if (box) box.textContent = "";
}

/** Where a message of the planner's own validation names a field: "uavs[0].start ..." */
function locFromMessage(msg) {
  const m = /^(\w+)\[(\d+)\](?:\.(\w+))?/.exec(msg);
  return m ? [m[1], m[2], m[3]].filter(Boolean).join(".") : null;
}

function showErrors(container, detail) {
  clearErrors(container);
  const items = Array.isArray(detail) ? detail : [{ loc: [], msg: String(detail) }];
  let n = 0;
  for (const item of items) {
    const loc = (item.loc ?? []).filter((p) => p !== "body").map(String);
    const messages = String(item.msg ?? "").replace(/^Value error, /, "").split("; ");
    for (const msg of messages) {
      let target = null;
      const keys = [];
      for (let k = loc.length; k > 0; k--) keys.push(loc.slice(0, k).join("."));
      const named = locFromMessage(msg);
      if (named) keys.push(named, named.split(".").slice(0, 2).join("."));
      for (const key of keys) {
        target = container.querySelector(`[data-loc="${CSS.escape(key)}"]`);
        if (target) break;
      }
      const id = `err-${container.id}-${n++}`;
      const note = el("span", { class: "field-error", id, text: msg });
      if (target && !target.classList.contains("field-errors")) {
        target.setAttribute("aria-invalid", "true");
        target.setAttribute("aria-describedby", id);
        if (target.matches("input, select, textarea")) target.after(note);
        else target.append(note);
      } else {
        container.querySelector(".field-errors")?.append(note);
      }
    }
  }
}

// --- scenario --------------------------------------------------------------------------

/** A scenario to edit and plan; `geographic` the file it was derived from, if any (its
 * area, zones, starts and goals are then drawn over the grid and editable). */
function setScenario(scenario, id, fit = true, geographic = null) {
  if (geographic) area.load(geographic); else area.clear();
  S.scenario = structuredClone(scenario);
  S.scenarioId = id;
  S.dirty = false;
  S.selected = 0;
  renderScenarioForm();
  field.setScenario(S.scenario, order, fit);
  $("scenario-status").textContent = id ? `stored as ${id}` : "not stored yet";
  clearErrors($("scenario-form"));
}

function edited(redraw = true) {
  S.dirty = true;
  $("scenario-status").textContent = "edited (stored on Plan)";
  if (redraw) {
    try { field.setScenario(S.scenario, order, false); } catch { /* half-typed grid */ }
  }
}

function renderScenarioForm() {
  const s = S.scenario;
  for (const input of document.querySelectorAll("#scenario-form [data-bind]")) {
    const path = input.dataset.bind.split(".");
    let v = s;
    for (const p of path) v = v?.[p];
    input.value = v ?? "";
  }
  const body = $("uav-table").querySelector("tbody");
  body.replaceChildren();
  s.uavs.forEach((u, i) => {
    const num = (key, step, label) => el("input", {
      type: "number", step, value: u[key] ?? "", "data-loc": `uavs.${i}.${key}`, "aria-label": `${u.id} ${label}`,
      class: "narrow", onchange: (e) => { u[key] = e.target.value === "" ? undefined : Number(e.target.value); edited(); },
    });
    body.append(el("tr", {},
      el("td", {}, el("input", {
        type: "radio", name: "sel-uav", checked: i === S.selected, "aria-label": `select ${u.id}`,
        onchange: () => { S.selected = i; },
      })),
      el("td", {}, el("span", { class: "swatch", style: `--c:${colourOf(i)}` }), el("input", {
        value: u.id, "data-loc": `uavs.${i}.id`, "aria-label": `UAV ${i + 1} id`, class: "narrow",
        onchange: (e) => { u.id = e.target.value; edited(); },
      })),
      el("td", {}, num("speed", "any", "speed (cells/s)")),
      el("td", {}, num("radius", "any", "radius (cells)")),
      el("td", { "data-loc": `uavs.${i}.start`, text: u.start.join(",") }),
      el("td", { "data-loc": `uavs.${i}.goal`, text: u.goal.join(",") }),
      el("td", {}, el("button", {
        type: "button", text: "×", "aria-label": `remove ${u.id}`, disabled: s.uavs.length <= 1,
        onclick: () => { s.uavs.splice(i, 1); S.selected = 0; renderScenarioForm(); edited(); },
      })),
    ));
  });
  const objects = s.non_uav_objects;
  const count = Array.isArray(objects) ? `${objects.length} objects` : `${objects.random} random objects (seed ${objects.seed ?? 0})`;
  $("sc-counts").textContent = `${s.obstacles.length} obstacles, ${count}`;
}

function bindInput(input) {
  input.addEventListener("change", () => {
    const path = input.dataset.bind.split(".");
    let target = S.scenario;
    if (!target) return;
    if (path[0] === "origin" && !target.origin) target.origin = { lat: 0, lon: 0, alt_m: 0 };
    for (const p of path.slice(0, -1)) target = target[p];
    const raw = input.value;
    target[path[path.length - 1]] = input.type === "number" ? (raw === "" ? undefined : Number(raw)) : raw;
    edited();
  });
}

function toggleCell(list, cell) {
  const i = list.findIndex(([x, y]) => x === cell[0] && y === cell[1]);
  if (i >= 0) list.splice(i, 1); else list.push(cell);
}

function applyTool(cell) {
  const s = S.scenario;
  if (!s) return;
  const tool = document.querySelector('input[name="tool"]:checked').value;
  const uav = s.uavs[S.selected];
  if (tool === "start") uav.start = cell;
  else if (tool === "goal") uav.goal = cell;
  else if (tool === "obstacle") toggleCell(s.obstacles, cell);
  else if (tool === "object") {
    if (!Array.isArray(s.non_uav_objects)) s.non_uav_objects = []; // random ones become explicit
    toggleCell(s.non_uav_objects, cell);
  } else return;
  renderScenarioForm();
  edited();
}

function addUav() {
  const s = S.scenario;
  if (!s) return;
  const used = new Set(s.uavs.map((u) => u.id));
  let k = s.uavs.length + 1;
  while (used.has(`uav${k}`)) k++;
  s.uavs.push({ id: `uav${k}`, start: [0, 0], goal: [s.grid.width - 1, s.grid.height - 1], speed: 1, radius: 0.3 });
  S.selected = s.uavs.length - 1;
  renderScenarioForm();
  edited();
}

async function storeScenario() {
  clearErrors($("scenario-form"));
  try {
    const { data } = await post("/scenarios", S.scenario);
    S.scenarioId = data.id;
    S.dirty = false;
    $("scenario-status").textContent = `stored as ${data.id}`;
    loadStoredList();
    return true;
  } catch (error) {
    if (error.status === 422) {
      showErrors($("scenario-form"), error.detail);
      say("the scenario is not valid: see the fields marked", "error");
    } else fail(error);
    return false;
  }
}

async function loadCases() {
  const cases = await get("/cases");
  $("case-select").replaceChildren(...cases.map((c) => el("option", {
    value: c.name, text: `${c.name}: ${c.uavs} UAVs, ${c.grid[0]}×${c.grid[1]}`,
  })));
}

async function loadStoredList() {
  const stored = await getAll("/scenarios");
  const select = $("stored-select");
  const keep = select.value;
  select.replaceChildren(el("option", { value: "", text: "(none)" }),
    ...stored.reverse().map((s) => el("option", { value: s.id, text: `${s.name} (${s.id})` })));
  select.value = keep;
}

// --- planning ----------------------------------------------------------------------------

function planRequest() {
  const int = (id) => Number.parseInt($(id).value, 10);
  const budget = $("pl-budget").value.trim();
  const candidates = int("pl-candidates");
  return {
    algorithm: $("pl-algorithm").value, objective: $("pl-objective").value,
    seed: int("pl-seed"), population: int("pl-population"), iterations: int("pl-iterations"),
    time_budget_s: budget === "" || Number(budget) === 0 ? null : Number(budget),
    candidates,
    // candidates are timed at the speed the Fly section will fly (only then is it sent)
    ...(candidates > 1 ? { flight_speed_m_s: Number($("fl-speed").value) } : {}),
    wait_s: 0, // always a job: the progress bar shows what the planner is doing
  };
}

async function requestPlan() {
  if (!S.scenario) { say("load or build a scenario first", "error"); return; }
  if (area.dirty) { say("the area on the map changed: Derive the grid first (or Clear it)", "error"); return; }
  clearErrors($("plan-form"));
  if (!S.scenarioId || S.dirty) {
    if (!(await storeScenario())) return;
  }
  try {
    const { status, data } = await post(`/scenarios/${S.scenarioId}/plans`, planRequest());
    if (status === 201) showPlan(data);
    else watchJob(data);
  } catch (error) {
    if (error.status === 422) showErrors($("plan-form"), error.detail);
    fail(error);
  }
}

function watchJob(job) {
  S.job = job;
  $("job-row").hidden = false;
  $("cancel-job-btn").hidden = false;
  showJob(job);
  S.jobWs?.close();
  const ws = new WebSocket(wsUrl(`/jobs/${job.id}/live`));
  S.jobWs = ws;
  ws.onmessage = (m) => showJob(JSON.parse(m.data));
  ws.onclose = async () => {
    if (S.jobWs !== ws) return;
    S.jobWs = null;
    if (S.job?.id === job.id && !FINAL_JOB.has(S.job.state)) showJob(await get(`/jobs/${job.id}`));
  };
}

async function showJob(job) {
  if (S.job?.id !== job.id) return;
  const already = FINAL_JOB.has(S.job.state) && S.job.shown;
  S.job = { ...job, shown: S.job.shown };
  $("job-progress").value = job.percent ?? 0;
  const safe = job.first_safe_s != null ? `, first safe after ${fmt(job.first_safe_s)} s` : "";
  $("job-status").textContent = `${job.state} ${fmt(job.percent, 0)} %, best cost ${fmt(job.best_cost)}${safe}`;
  if (!FINAL_JOB.has(job.state) || already) return;
  S.job.shown = true;
  $("cancel-job-btn").hidden = true;
  if (job.state === "done" && job.plan_id) showPlan(await get(`/plans/${job.plan_id}`));
  else say(`planning ${job.state}${job.error ? `: ${job.error}` : ""}`, "error");
}

async function cancelJob() {
  if (!S.job) return;
  try { showJob((await post(`/jobs/${S.job.id}/cancel`)).data); } catch (error) { fail(error); }
}

function showPlan(planOut) {
  S.plan = planOut;
  S.replanned = new Set();
  field.clearReported();
  const plan = planOut.plan;
  drawPlan();
  S.tMax = Math.max(...plan.uavs.map((u) => u.trajectory[u.trajectory.length - 1][0]));
  $("time-slider").max = String(S.tMax);
  setTime(0);
  renderMetrics(planOut);
  renderLegend(plan);
  renderBindings();
  say(plan.feasible ? `plan ${planOut.id}: safe` : `plan ${planOut.id}: NOT safe (${plan.metrics.conflicts} conflicts)`,
    plan.feasible ? "info" : "error");
}

function drawPlan() {
  if (!S.plan) return;
  const { plan } = S.plan;
  field.setPlan(plan, order, S.scenario?.grid.cell_size_m ?? 10, radii(), S.replanned, S.plan.trajectories_wgs84);
  if (S.scenario && !Array.isArray(S.scenario.non_uav_objects)) {
    field.planObjects(plan.non_uav_objects); // random ones: the plan says where they fell
  }
}

function renderMetrics(planOut) {
  const { plan } = planOut;
  const m = plan.metrics;
  const cell = S.scenario?.grid.cell_size_m ?? 10;
  $("plan-id").textContent = planOut.id;
  const rows = [
    ["safe", plan.feasible ? "yes" : `no: ${m.conflicts} conflicts`],
    ["min separation", m.min_separation == null ? "–" : `${fmt(m.min_separation)} cells (${fmt(m.min_separation * cell, 1)} m)`],
    ["total length", `${fmt(m.total_length)} cells`],
    ...plan.uavs.map((u) => [`  ${u.id}`, `${fmt(u.length)} cells (shortest ${fmt(u.shortest_length)}), deviation ${fmt(u.deviation)}`]),
    ["mean deviation", `${fmt(m.mean_deviation)} cells`],
    ["first safe after", m.first_safe_s == null ? "–" : `${fmt(m.first_safe_s)} s`],
    ["cost / J", `${fmt(m.cost)} / ${fmt(m.J)}`],
    ["planning", `${fmt(m.seconds)} s, ${m.nfe} evaluations, ${plan.algorithm} ${plan.objective} seed ${plan.seed}, ${plan.stop_reason ?? ""}`],
    ...candidateRows(planOut.candidates),
    ["timed flight", "…", "timed-flight"],
  ];
  const body = $("metrics").querySelector("tbody");
  body.replaceChildren(...rows.map(([k, v, id]) => el("tr", {}, el("th", { scope: "row", text: k }), el("td", { text: v, id }))));
  $("metrics").hidden = false;
  showTiming();
}

/** A plan chosen of several: what each candidate's flight was timed at when it was
 * chosen, or why it could not be flown, and which one the plan is. */
function candidateRows(candidates) {
  if (!candidates) return [];
  const outcome = (c) => c.same_as != null ? `the same paths as seed ${c.same_as}`
    : c.refusal ?? `${fmt(c.duration_s, 1)} s`;
  return [
    ["candidates", `${candidates.length}, the soonest flown kept`],
    ...candidates.map((c) => [`  seed ${c.seed}, ${fmt(c.clearance_m, 1)} m`,
      `${outcome(c)}${c.kept ? " (kept)" : ""}`]),
  ];
}

/** How long the plan flies with the Fly section's speed, altitude and finish, as the service
 * times it (ArduCopter's default limits), before anything is uploaded; or why it cannot be
 * flown so. */
async function showTiming() {
  const planOut = S.plan;
  if (!planOut || !$("timed-flight")) return;
  const speed = $("fl-speed").value;
  const options = timingOptions();
  let text;
  try {
    const timing = await get(`/plans/${planOut.id}/timing?${options}`);
    text = `${fmt(timing.duration_s, 1)} s to the last goal at ${fmt(timing.max_speed_m_s, 1)} m/s`;
  } catch (error) {
    const why = Array.isArray(error.detail) ? error.detail.map((d) => d.msg).join("; ") : error.message;
    text = `at ${speed} m/s: ${why}`;
  }
  if (S.plan === planOut && timingOptions() === options) $("timed-flight").textContent = text;
}

const timingOptions = () => new URLSearchParams({
  max_speed_m_s: $("fl-speed").value, altitude_m: $("fl-alt").value, finish: $("fl-finish").value,
}).toString();

function renderLegend(plan) {
  $("legend").replaceChildren(...plan.uavs.map((u) => el("span", { class: "legend-item" },
    el("span", { class: "swatch", style: `--c:${colourOf(order(u.id))}` }), u.id)));
}

// --- the time slider and the animation ---------------------------------------------------

function setTime(t) {
  S.t = Math.min(Math.max(t, 0), S.tMax);
  $("time-slider").value = String(S.t);
  $("time-label").textContent = `t = ${fmt(S.t, 1)} s of ${fmt(S.tMax, 1)} s`;
  field.showTime(S.t);
  const plan = S.plan?.plan;
  if (!plan || plan.uavs.length < 2) { $("sep-label").textContent = ""; return; }
  const at = plan.uavs.map((u) => positionAt(u.trajectory, S.t));
  let best = Infinity;
  for (let i = 0; i < at.length; i++) for (let j = i + 1; j < at.length; j++) {
    best = Math.min(best, Math.hypot(at[i][0] - at[j][0], at[i][1] - at[j][1]));
  }
  $("sep-label").textContent = `closest pair now ${fmt(best)} cells`;
}

function togglePlay(on = !S.playing) {
  S.playing = on && Boolean(S.plan);
  $("play-btn").setAttribute("aria-pressed", String(S.playing));
  $("play-btn").textContent = S.playing ? "Stop" : "Play";
  if (!S.playing) return;
  if (S.t >= S.tMax) setTime(0);
  let last = performance.now();
  const frame = (now) => {
    if (!S.playing) return;
    setTime(S.t + (now - last) / 1000);
    last = now;
    if (S.t >= S.tMax) togglePlay(false);
    else requestAnimationFrame(frame);
  };
  requestAnimationFrame(frame);
}

// --- vehicles and bindings ---------------------------------------------------------------

async function refreshVehicles() {
  try {
    const [vehicles, discovered] = await Promise.all([get("/vehicles"), get("/vehicles/discovered")]);
    S.vehicles = vehicles;
    S.discovered = discovered.filter((d) => !d.vehicle_id);
    const flying = new Set(S.flightWs ? Object.values(S.flight?.bindings ?? {}) : []);
    for (const v of vehicles) {
      if (!flying.has(v.id)) updateVehicleRow(v.id, { vehicle_id: v.id, name: v.name, ...v.live });
    }
    field.showParked(vehicles.filter((v) => !flying.has(v.id))
      .map((v) => ({ id: v.id, name: v.name, lat: v.live.lat, lon: v.live.lon, online: v.live.online })));
    fitOnVehicles();
    area.vehiclesChanged();
    renderBindings(true);
  } catch (error) {
    say(`cannot read the vehicles: ${error.message}`, "error");
  }
}

/** Nothing loaded or drawn yet: the map shows the vehicles where they are (again when
 * one more reports a position). */
function fitOnVehicles() {
  if (S.scenario || area.hasDrawing()) return;
  const placed = S.vehicles.filter((v) => v.live?.lat != null && v.live?.lon != null);
  const key = placed.map((v) => v.id).join(",");
  if (!placed.length || key === S.fittedOn) return;
  S.fittedOn = key;
  field.fitTo(placed.map((v) => [v.live.lat, v.live.lon]));
}

function renderBindings(keep = false) {
  const body = $("binding-table").querySelector("tbody");
  const uavs = S.plan?.plan.uavs ?? S.scenario?.uavs ?? [];
  const chosen = new Map([...body.querySelectorAll("select")].map((s) => [s.dataset.uav, s.value]));
  const options = () => [
    ...S.vehicles.map((v) => el("option", { value: v.id, text: `${v.name} (${v.id})${v.live.online ? "" : " offline"}` })),
    ...S.discovered.map((d) => el("option", { value: `heard:${d.sysid}`, text: `heard: sysid ${d.sysid} on ${d.connection}` })),
  ];
  if (keep && body.children.length === uavs.length) {
    for (const select of body.querySelectorAll("select")) {
      const value = select.value;
      if (document.activeElement === select) continue; // do not pull a list from under the operator
      select.replaceChildren(...options());
      select.value = value;
    }
    return;
  }
  const startsAt = area.startVehicles(); // a UAV that starts where vehicle X is flies X
  body.replaceChildren(...uavs.map((u, i) => {
    const select = el("select", { "data-uav": u.id, "data-loc": `bindings.${u.id}`, "aria-label": `vehicle for ${u.id}` }, ...options());
    const fallback = startsAt.get(u.id) ?? S.vehicles[i]?.id ?? (S.discovered[i - S.vehicles.length] ? `heard:${S.discovered[i - S.vehicles.length].sysid}` : "");
    select.value = chosen.get(u.id) ?? fallback;
    return el("tr", {}, el("th", { scope: "row" }, el("span", { class: "swatch", style: `--c:${colourOf(i)}` }), u.id), el("td", {}, select));
  }));
}

async function bindings() {
  const out = {};
  for (const select of $("binding-table").querySelectorAll("select")) {
    let id = select.value;
    if (id.startsWith("heard:")) { // a vehicle heard on the discovery port: register it first
      const sysid = Number(id.slice(6));
      const heard = S.discovered.find((d) => d.sysid === sysid);
      id = (await post("/vehicles", { connection: heard.connection, sysid, name: `sysid ${sysid}` })).data.id;
    }
    out[select.dataset.uav] = id;
  }
  return out;
}

const rows = new Map(); // vehicle id -> {row, cells}

function updateVehicleRow(vehicleId, v) {
  let entry = rows.get(vehicleId);
  if (!entry) {
    const cells = {};
    const row = el("tr", { "data-vehicle": vehicleId });
    for (const key of ["uav", "link", "mode", "alt", "hdg", "item", "lag", "flags"]) {
      cells[key] = el("td", { class: `col-${key}` });
    }
    const command = (cmd, label) => el("button", {
      type: "button", class: cmd === "continue" ? "small" : "danger small", text: label,
      "aria-label": `${label} vehicle ${vehicleId}`,
      "data-command": cmd, onclick: () => commandVehicle(vehicleId, cmd),
    });
    // The commands right after the name, so that they are never scrolled out of view.
    const commands = el("td", { class: "commands" }, command("hold", "Hold"), command("land", "Land"), command("rtl", "RTL"), command("continue", "Go on"));
    row.append(cells.uav, commands, ...["link", "mode", "alt", "hdg", "item", "lag", "flags"].map((k) => cells[k]));
    $("vehicle-table").querySelector("tbody").append(row);
    entry = { row, cells };
    rows.set(vehicleId, entry);
  }
  const c = entry.cells;
  const p = v.progress ?? {};
  // The UAV it flies as, else the vehicle's name; the full name and id on hover.
  if (v.name) entry.name = v.name;
  if (v.uav_id) {
    entry.uav = v.uav_id;
    c.uav.style.setProperty("--c", colourOf(order(v.uav_id)));
    c.uav.className = "col-uav swatched";
  }
  c.uav.textContent = entry.uav ?? entry.name ?? vehicleId;
  c.uav.title = `${entry.name ?? ""} (vehicle ${vehicleId})`;
  // With the link down every value is the last one heard: shown as such, with its age.
  const heard = v.seconds_since_heard == null ? "" : `last heard ${fmt(v.seconds_since_heard, 1)} s ago`;
  c.link.textContent = v.online ? "up" : v.seconds_since_heard == null ? "DOWN" : `DOWN ${fmt(v.seconds_since_heard, 0)} s`;
  c.link.title = heard;
  c.link.className = v.online ? "col-link ok" : "col-link bad";
  entry.row.classList.toggle("stale", Boolean(v.stale));
  entry.row.title = v.stale ? `not heard: mode, altitude, item and flags as ${heard}` : "";
  c.mode.textContent = v.mode ?? "?";
  c.alt.textContent = v.relative_alt_m == null ? "–" : `${fmt(v.relative_alt_m, 1)} m`;
  c.hdg.textContent = v.heading_deg == null ? "–" : `${fmt(v.heading_deg, 0)}°`;
  c.item.textContent = v.mission_seq == null ? "–" : `${v.mission_seq}/${v.mission_total ?? "?"}`;
  c.lag.textContent = p.lag_s == null ? "–" : `${fmt(p.lag_s, 1)} s`;
  // Who waits for whom: the passing order stops (or edges on) a vehicle until another
  // has left the stretch they share.
  const waits = p.waits_for ? `waits for ${p.waits_for}` : "";
  const flags = [v.armed ? (v.stale ? "armed?" : "armed") : "", waits, ...["held", "withdrawn", "landing", "finished"].filter((k) => p[k])];
  c.flags.textContent = flags.filter(Boolean).join(" ");
  c.flags.classList.toggle("waiting", Boolean(waits));
  entry.row.dataset.online = String(Boolean(v.online));
}

async function commandVehicle(vehicleId, command) {
  try {
    const { data } = await post(`/vehicles/${vehicleId}/${command}`);
    say(`${vehicleId} ${command}: ${data.ok ? "done" : "refused"} ${data.detail ?? ""}`, data.ok ? "info" : "error");
  } catch (error) { fail(error); }
}

// --- flights -----------------------------------------------------------------------------

function flightOptions() {
  return {
    altitude_m: Number($("fl-alt").value), max_speed_m_s: Number($("fl-speed").value),
    finish: $("fl-finish").value,
  };
}

function setFlight(flight) {
  const changed = S.flight?.id !== flight.id;
  S.flight = flight;
  $("flight-id").textContent = flight.id;
  showFlightState(flight.state);
  if (changed) {
    field.clearVehicles();
    $("events").replaceChildren();
    S.eventIds = new Set();
  }
  if (!FINAL_FLIGHT.has(flight.state) && !S.flightWs) watchFlight(flight.id);
}

function showFlightState(state) {
  const badge = $("flight-state");
  badge.textContent = state;
  badge.dataset.state = state;
  if (S.flight) S.flight.state = state;
}

function watchFlight(flightId, retries = 5) {
  const ws = new WebSocket(wsUrl(`/flights/${flightId}/live`));
  S.flightWs = ws;
  ws.onmessage = (m) => onLive(JSON.parse(m.data));
  ws.onclose = async () => {
    if (S.flightWs !== ws) return;
    S.flightWs = null;
    if (S.flight?.id !== flightId) return;
    const flight = await get(`/flights/${flightId}`);
    setFlight(flight);
    if (!FINAL_FLIGHT.has(flight.state) && retries > 0 && !S.flightWs) {
      setTimeout(() => { if (!S.flightWs && S.flight?.id === flightId) watchFlight(flightId, retries - 1); }, 1000);
    }
  };
}

function onLive(message) {
  if (message.type === "state") {
    showFlightState(message.state);
    S.live = message;
    field.updateVehicles(message.vehicles, order);
    for (const v of message.vehicles) updateVehicleRow(v.vehicle_id, v);
    noteTimings(message);
    followClock(message);
  } else if (message.type === "event") {
    if (message.kind === KIND.PROGRESS) return;
    addEvent(message);
  } else if (message.type === "dropped") { // this page fell behind: the service says how far
    addEvent({ kind: "live messages missed", count: message.count });
  }
}

function noteTimings(message) {
  if (timings.startClicked == null) return;
  const now = performance.now();
  if (timings.firstLiveAfterStart == null) timings.firstLiveAfterStart = now - timings.startClicked;
  if (!timings.startPositions) {
    timings.startPositions = Object.fromEntries(message.vehicles.map((v) => [v.uav_id, [v.lat, v.lon]]));
  } else if (timings.firstMoveAfterStart == null) {
    const moved = message.vehicles.some((v) => {
      const [lat, lon] = timings.startPositions[v.uav_id] ?? [v.lat, v.lon];
      return v.lat != null && Math.hypot((v.lat - lat) * 111320, (v.lon - lon) * 111320 * Math.cos(lat * Math.PI / 180)) > 0.5;
    });
    if (moved) timings.firstMoveAfterStart = now - timings.startClicked;
  }
  if (message.state === "flying" && timings.flyingAfterStart == null) timings.flyingAfterStart = now - timings.startClicked;
  const parts = [];
  if (timings.firstLiveAfterStart != null) parts.push(`first live positions ${fmt(timings.firstLiveAfterStart / 1000)} s`);
  if (timings.firstMoveAfterStart != null) parts.push(`first movement ${fmt(timings.firstMoveAfterStart / 1000, 1)} s`);
  if (timings.flyingAfterStart != null) parts.push(`flying ${fmt(timings.flyingAfterStart / 1000, 1)} s`);
  $("timings").textContent = parts.length ? `After start: ${parts.join(", ")}` : "";
}

function followClock(message) {
  if (S.playing || !S.plan || !message.pace_factor) return;
  const clocks = message.vehicles.map((v) => v.progress?.clock_s).filter((c) => c != null && c > 0);
  if (clocks.length) setTime(Math.max(...clocks) / message.pace_factor);
}

// A list shows its items, a pair as "first>second" (LeadTaken's turned: who goes first).
const shown = (v) => (Array.isArray(v) ? v.map((x) => [].concat(x).join(">")).join(",") : v);

function describeEvent(e) {
  const skip = new Set(["type", "kind", "at", "uav_id", "id"]);
  return Object.entries(e)
    .filter(([k, v]) => !skip.has(k) && v !== "" && v != null && (typeof v !== "object" || Array.isArray(v)))
    .map(([k, v]) => `${k}=${typeof v === "number" ? fmt(v) : shown(v)}`).join(" ");
}

function addEvent(e) {
  const list = $("events");
  const item = el("li", { "data-kind": e.kind },
    el("strong", { text: e.kind }), e.uav_id ? ` ${e.uav_id}` : "", el("span", { class: "muted", text: ` ${describeEvent(e)}` }));
  list.prepend(item);
  while (list.children.length > EVENTS_SHOWN) list.lastChild.remove();
  if (e.kind === KIND.OBJECT_REPORTED) showReplan(e);
}

async function bindAndUpload() {
  if (!S.plan) { say("plan first", "error"); return; }
  clearErrors($("flight-form"));
  const button = $("upload-btn");
  button.disabled = true; // only this button: the fleet's commands stay available
  try {
    const reuse = S.flight && S.flight.plan_id === S.plan.id && ["created", "upload_failed", "uploaded"].includes(S.flight.state);
    if (!reuse) {
      const body = { plan_id: S.plan.id, bindings: await bindings(), ...flightOptions() };
      try {
        setFlight((await post("/flights", body)).data);
      } catch (error) {
        if (error.status === 422) showErrors($("flight-form"), error.detail);
        throw error;
      }
    }
    say(`flight ${S.flight.id}: uploading…`);
    const { data } = await post(`/flights/${S.flight.id}/upload`);
    // The live stream passes events on only to listeners that joined after the upload
    // made the flight active: join again now (see docs/console.md, "API notes").
    const stale = S.flightWs;
    S.flightWs = null;
    stale?.close();
    setFlight(data.flight);
    renderAnswers($("upload-results"), data.vehicles);
    say(`flight ${S.flight.id}: ${data.flight.state}`, data.flight.state === "uploaded" ? "info" : "error");
  } catch (error) {
    fail(error);
  } finally {
    button.disabled = false;
  }
}

function renderAnswers(list, answers) {
  list.replaceChildren(...answers.map((a) => el("li", { class: a.ok ? "ok" : "bad", "data-uav": a.uav_id },
    `${a.uav_id} → ${a.vehicle_id}: ${a.ok ? "ok" : "FAILED"} `, el("span", { class: "muted", text: a.detail ?? "" }))));
}

async function startFlight() {
  if (!S.flight) { say("upload first", "error"); return; }
  for (const key of Object.keys(timings)) delete timings[key];
  timings.startClicked = performance.now();
  try {
    setFlight((await post(`/flights/${S.flight.id}/start`)).data);
    say(`flight ${S.flight.id}: ${S.flight.state}`);
  } catch (error) { fail(error); }
}

async function fleetCommand(action, body) {
  if (!S.flight) { say("no flight to command: per-vehicle commands are in the vehicle table", "error"); return; }
  try {
    const { data } = await post(`/flights/${S.flight.id}/${action}`, body);
    const flight = data.flight ?? data;
    setFlight(flight);
    const refused = (data.vehicles ?? []).filter((v) => !v.ok);
    say(`${action}: flight ${flight.state}${refused.length ? `; refused by ${refused.map((v) => v.uav_id).join(", ")}` : ""}`,
      refused.length ? "error" : "info");
  } catch (error) { fail(error); }
}

// --- reporting an object ---------------------------------------------------------------------

function setReportMode(on) {
  S.reportMode = on;
  $("report-btn").setAttribute("aria-pressed", String(on));
  $("map").classList.toggle("reporting", on);
  if (on) say("click the cell where the object is (or type it under Scenario → Cell and Apply)");
}

function onCell(cell) {
  $("cell-x").value = cell[0];
  $("cell-y").value = cell[1];
  if (S.reportMode) reportObject(cell);
  else applyTool(cell);
}

async function reportObject(cell) {
  setReportMode(false);
  if (!S.flight) { say("no flight to report to", "error"); return; }
  say(`reporting an object at ${cell.join(", ")}…`);
  try {
    const { data } = await post(`/flights/${S.flight.id}/objects`, { cell });
    showReplan(data);
  } catch (error) { fail(error); }
}

function showReplan(answer) {
  const key = `${answer.cell}@${answer.plan_time_s}`;
  if (S.lastReplan === key) return; // the answer and its event: show once
  S.lastReplan = key;
  field.reportedObject(answer.cell);
  for (const [uav, path] of Object.entries(answer.paths ?? {})) {
    const planned = S.plan?.plan.uavs.find((u) => u.id === uav);
    if (planned) planned.trajectory = path; // the new path, in the plan's own time
    S.replanned.add(uav);
  }
  drawPlan();
  field.showTime(S.t);
  const list = (xs) => (xs?.length ? xs.join(", ") : "none");
  $("replan-result").replaceChildren(
    el("p", {}, el("strong", { text: `Object at ${answer.cell.join(", ")}` }), ` (flight clock ${fmt(answer.plan_time_s, 1)} s)`),
    el("p", { "data-field": "touched", text: `touched: ${list(answer.touched)}` }),
    el("p", { "data-field": "changed", text: `replanned: ${list(answer.changed)}` }),
    el("p", { "data-field": "unresolved", class: answer.unresolved?.length ? "bad" : "", text: `unresolved: ${list(answer.unresolved)}` }),
    el("p", { class: answer.feasible ? "ok" : "bad", text: answer.feasible ? "the fleet is still separated" : "NOT separated" }),
    el("p", { class: "muted", text: answer.explanation ?? "" }),
  );
  say(`object at ${answer.cell.join(", ")}: replanned ${list(answer.changed)}`);
}

// --- look back -----------------------------------------------------------------------------

async function loadFlights() {
  const flights = await getAll("/flights");
  const select = $("flight-select");
  const keep = select.value;
  select.replaceChildren(...flights.reverse().map((f) => el("option", { value: f.id, text: `${f.id}: ${f.state}` })));
  if (keep) select.value = keep;
}

async function lookBack() {
  const id = $("flight-select").value;
  if (!id) return;
  try {
    const flight = await get(`/flights/${id}`);
    const planOut = await get(`/plans/${flight.plan_id}`);
    const stored = await get(`/scenarios/${planOut.scenario_id}`);
    const watched = S.flight?.id === id;
    setScenario(stored.scenario, stored.id, !watched, stored.geographic);
    showPlan(planOut);
    const events = await allEvents(id);
    const ended = events.find((e) => e.kind === KIND.FLIGHT_ENDED);
    const reached = events.filter((e) => e.kind === KIND.ITEM_REACHED);
    const replans = events.filter((e) => e.kind === KIND.OBJECT_REPORTED);
    for (const r of replans) field.reportedObject(r.data.cell);
    const lines = [
      `flight ${id}: ${flight.state}${flight.note ? ` (${flight.note})` : ""}`,
      ended ? `measured separation ${fmt(ended.data.min_separation_m)} m${ended.data.closest_pair ? ` (${ended.data.closest_pair.join(" – ")})` : ""}, outcome ${ended.data.outcome}` : "no FlightEnded event",
      `${reached.length} waypoints reached, ${replans.length} objects reported, ${events.length} events`,
    ];
    if (!watched) field.clearVehicles();
    // The flown tracks (positions stored once a second), then the waypoints reached.
    const samples = events.filter((e) => e.kind === KIND.POSITIONS);
    for (const uav of Object.keys(flight.bindings)) {
      const track = samples.map((e) => e.data.vehicles[uav]).filter((p) => p && p[0] != null);
      if (track.length) field.flownTrack(order(uav), track.map(([lat, lon]) => [lat, lon]));
    }
    lines.push(`${samples.length} stored positions per vehicle (one a second): the flown tracks`);
    for (const uav of Object.keys(flight.bindings)) {
      const mine = reached.filter((e) => e.uav_id === uav);
      if (!mine.length) continue;
      try {
        const doc = await get(`/flights/${id}/missions/${uav}.plan`);
        const ardupilot = doc.mission.firmwareType === 3;
        const bySeq = new Map(doc.mission.items.map((it) => [ardupilot ? it.doJumpId : it.doJumpId - 1, it]));
        const points = mine.map((e) => bySeq.get(e.data.seq)).filter((it) => it && it.params[4] && it.params[5])
          .map((it) => [it.params[4], it.params[5]]);
        field.reachedPoints(uav, order(uav), points);
        // The last item is the landing: its descent is not in the plan's schedule.
        const lateness = (e) => e.data.plan_time_s - e.data.scheduled_s;
        const last = mine.reduce((a, e) => (e.data.seq > a.data.seq ? e : a));
        const way = mine.filter((e) => e !== last);
        const late = way.length ? `at most ${fmt(Math.max(...way.map(lateness)), 1)} s late on the way` : "";
        lines.push(`${uav}: ${mine.length} waypoints reached, ${late}; last one ${fmt(lateness(last), 1)} s after its time`);
      } catch (error) { lines.push(`${uav}: ${error.message}`); }
    }
    $("lookback-result").replaceChildren(...lines.map((t) => el("p", { text: t })));
    $("events").replaceChildren();
    for (const e of events.slice(-EVENTS_SHOWN)) addEvent({ kind: e.kind, uav_id: e.uav_id, ...e.data });
  } catch (error) { fail(error); }
}

// --- wiring ----------------------------------------------------------------------------------

function wire() {
  field.onCell = onCell;
  area.wire();
  document.querySelectorAll("#scenario-form [data-bind]").forEach(bindInput);
  $("load-case-btn").addEventListener("click", async () => {
    try { setScenario(await get(`/cases/${encodeURIComponent($("case-select").value)}`), null); } catch (error) { fail(error); }
  });
  $("load-stored-btn").addEventListener("click", async () => {
    const id = $("stored-select").value;
    if (!id) return;
    try { const s = await get(`/scenarios/${id}`); setScenario(s.scenario, s.id, true, s.geographic); } catch (error) { fail(error); }
  });
  $("add-uav-btn").addEventListener("click", addUav);
  $("save-scenario-btn").addEventListener("click", () => S.scenario && storeScenario());
  $("cell-apply-btn").addEventListener("click", () => {
    const x = Number.parseInt($("cell-x").value, 10), y = Number.parseInt($("cell-y").value, 10);
    if (Number.isInteger(x) && Number.isInteger(y)) onCell([x, y]);
  });
  $("plan-btn").addEventListener("click", requestPlan);
  $("cancel-job-btn").addEventListener("click", cancelJob);
  $("play-btn").addEventListener("click", () => togglePlay());
  $("time-slider").addEventListener("input", (e) => { togglePlay(false); setTime(Number(e.target.value)); });
  $("upload-btn").addEventListener("click", bindAndUpload);
  for (const id of ["fl-speed", "fl-alt", "fl-finish"]) $(id).addEventListener("change", showTiming);
  $("start-btn").addEventListener("click", startFlight);
  $("cancel-flight-btn").addEventListener("click", () => fleetCommand("cancel"));
  $("pause-btn").addEventListener("click", () => fleetCommand("pause"));
  $("continue-btn").addEventListener("click", () => fleetCommand("continue"));
  $("resume-btn").addEventListener("click", () => fleetCommand("resume"));
  $("abort-rtl-btn").addEventListener("click", () => fleetCommand("abort", { mode: "rtl" }));
  $("abort-land-btn").addEventListener("click", () => fleetCommand("abort", { mode: "land" }));
  $("report-btn").addEventListener("click", () => setReportMode(!S.reportMode));
  $("refresh-flights-btn").addEventListener("click", () => loadFlights().catch(fail));
  $("show-flight-btn").addEventListener("click", lookBack);
  const tokenButton = $("token-btn");
  const tokenLabel = () => { tokenButton.textContent = hasToken() ? "Forget token" : "Set token"; };
  tokenButton.addEventListener("click", async () => {
    if (hasToken()) forgetToken();
    else await token().catch(() => {});
    tokenLabel();
  });
  $("token-dialog").addEventListener("close", () => setTimeout(tokenLabel));
  tokenLabel();
  document.addEventListener("keydown", (e) => {
    if (e.key === "Escape" && S.reportMode) setReportMode(false);
  });
}

async function main() {
  wire();
  await Promise.all([loadCases(), loadStoredList(), refreshVehicles(), loadFlights()]).catch(fail);
  setInterval(refreshVehicles, POLL_MS);
  // A flight still open from before (another tab, a reload): show it.
  const open = (await get("/flights?open=true").catch(() => [])).at(-1);
  if (open) {
    $("flight-select").value = open.id;
    await lookBack();
    setFlight(open);
  }
  await sayWarnings();
  document.body.dataset.ready = "true";
}

/** What the service runs without, said at start: a taken discovery port means that no
 * vehicle announcing itself will be heard. */
async function sayWarnings() {
  const health = await fetch("/health/ready").then((r) => r.json()).catch(() => null);
  const warnings = health?.warnings ?? [];
  if (warnings.length) say(warnings.join("; "), "error");
}

main();
