// The area on the map: a geographic scenario (docs/planner.md, "Geographic scenarios")
// drawn on the map or imported from a file, posted as GeoJSON. The service derives its
// grid, the page then plans and flies it as any grid scenario. One converter: a KML file
// is posted as it is and the service's GeoJSON of it comes back; nothing is converted here.
import { ApiError, postAs } from "./api.js";
import { colourOf } from "./field.js";

const GEOJSON = "application/geo+json";
const KML = "application/vnd.google-earth.kml+xml";
const PLAN_FILES = "QGroundControl .plan files are not read here: make them GeoJSON with "
  + "`mvo-gcs import FILE.plan ... -o area.geojson` and import that";
const $ = (id) => document.getElementById(id);
const round7 = (v) => Math.round(v * 1e7) / 1e7;
const lonLat = ([lat, lon]) => [round7(lon), round7(lat)];
const SAME_VERTEX_PX = 5; // a double click's two clicks add one vertex

function node(tag, attrs = {}, ...children) {
  const n = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "text") n.textContent = v;
    else if (k.startsWith("on")) n.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) n.setAttribute(k, v === true ? "" : v);
  }
  n.append(...children);
  return n;
}

function emptyUav(id) {
  return { id, startAt: null, vehicle: null, goalAt: null, speed: null, startProps: {}, goalProps: {} };
}

export class AreaEditor {
  /** hooks: say(text, kind), fail(error), stored(scenarioOut), vehicles() (the registered
   * vehicles as GET /vehicles lists them). */
  constructor(field, hooks) {
    this.field = field;
    this.hooks = hooks;
    this.reset();
    field.onMapClick = (latlng) => this.click(latlng);
    field.onMapDblClick = () => { if (this.sketch) this.closeShape(); };
  }

  reset() {
    this.props = {}; // the collection's other properties (margin_m, alt_m), kept
    this.area = null; // Feature
    this.zones = []; // Features: Polygon, MultiPolygon or Point with radius_m
    this.others = []; // rally points and anything else read from a file, kept as read
    this.uavs = [emptyUav("uav1")];
    this.selected = 0;
    this.sketch = null; // {kind: "area" | "no-fly", points: [[lat, lon]]}
    this.posted = []; // what each index of the last posted file was, for a 422's `feature`
    this.refused = null;
    this.dirty = false; // drawn or changed since the grid was derived (or nothing loaded)
  }

  tool() { return document.querySelector('input[name="geo-tool"]:checked').value; }

  setTool(value) {
    document.querySelector(`input[name="geo-tool"][value="${value}"]`).checked = true;
    this.toolChanged();
  }

  toolChanged() {
    const tool = this.tool();
    if (this.sketch && this.sketch.kind !== tool) this.cancelShape();
    this.field.setDrawing(tool === "area" || tool === "no-fly");
    const hints = {
      none: "",
      area: "click the area's corners; double-click the last one or press Close shape",
      "no-fly": "click the zone's corners; double-click the last one or press Close shape",
      start: `click where ${this.uavs[this.selected]?.id ?? "the UAV"} starts`,
      goal: `click ${this.uavs[this.selected]?.id ?? "the UAV"}'s goal`,
    };
    $("geo-hint").textContent = hints[tool] ?? "";
  }

  /** A click on the map: true when it was for the area (the grid's own tools get the rest). */
  click(latlng) {
    const tool = this.tool();
    const at = [latlng.lat, latlng.lng];
    if (tool === "area" || tool === "no-fly") {
      if (!this.sketch) this.sketch = { kind: tool, points: [] };
      const last = this.sketch.points.at(-1);
      const map = this.field.map;
      if (last && map.latLngToContainerPoint(last).distanceTo(map.latLngToContainerPoint(at)) < SAME_VERTEX_PX) return true;
      this.sketch.points.push(at);
      this.drawSketch();
      return true;
    }
    if (tool === "start" || tool === "goal") {
      const uav = this.uavs[this.selected];
      if (!uav) return true;
      if (tool === "start") { uav.startAt = at; uav.vehicle = null; } else uav.goalAt = at;
      this.edited();
      return true;
    }
    return false;
  }

  drawSketch() {
    const points = this.sketch?.points ?? [];
    this.field.setSketch(points);
    $("geo-close-btn").disabled = points.length < 3;
    $("geo-sketch").textContent = this.sketch ? `${this.sketch.kind}: ${points.length} points` : "";
  }

  closeShape() {
    const { kind, points } = this.sketch;
    if (points.length < 3) { this.hooks.say("a shape needs three corners at least", "error"); return; }
    const ring = [...points, points[0]].map(lonLat);
    const geometry = { type: "Polygon", coordinates: [ring] };
    if (kind === "area") {
      this.area = { type: "Feature", properties: { role: "area", name: "area" }, geometry };
    } else {
      const name = `zone ${this.zones.length + 1}`;
      this.zones.push({ type: "Feature", properties: { role: "no-fly", name }, geometry });
    }
    this.sketch = null;
    this.drawSketch();
    this.setTool("none");
    this.edited();
  }

  cancelShape() {
    this.sketch = null;
    this.drawSketch();
  }

  undoPoint() {
    if (!this.sketch) return;
    this.sketch.points.pop();
    this.drawSketch();
  }

  // --- the file --------------------------------------------------------------------------

  features() {
    const out = [];
    const refs = [];
    const add = (f, ref) => { out.push(f); refs.push(ref); };
    if (this.area) add(this.area, { kind: "area" });
    this.zones.forEach((z, i) => add(z, { kind: "zone", i }));
    this.uavs.forEach((u, i) => {
      const speed = u.speed ? { speed_m_s: u.speed } : {};
      if (u.startAt || u.vehicle) {
        add({
          type: "Feature",
          properties: { ...u.startProps, role: "start", uav: u.id, ...speed, ...(u.vehicle ? { vehicle: u.vehicle } : {}) },
          geometry: u.vehicle ? null : { type: "Point", coordinates: lonLat(u.startAt) },
        }, { kind: "start", i });
      }
      if (u.goalAt) {
        add({ type: "Feature", properties: { ...u.goalProps, role: "goal", uav: u.id }, geometry: { type: "Point", coordinates: lonLat(u.goalAt) } },
          { kind: "goal", i });
      }
    });
    this.others.forEach((f, i) => add(f, { kind: "other", i }));
    return { features: out, refs };
  }

  collection() {
    const cell = Number($("geo-cell").value);
    return {
      type: "FeatureCollection",
      properties: { ...this.props, name: $("geo-name").value || "area", cell_size_m: cell },
      features: this.features().features,
    };
  }

  /** Read a FeatureCollection (imported, or as the service stored it) into the editor. */
  load(doc) {
    this.reset();
    const { name, cell_size_m: cell, ...rest } = doc.properties ?? {};
    this.props = rest;
    $("geo-name").value = name ?? "area";
    if (cell != null) $("geo-cell").value = cell;
    this.uavs = [];
    const uav = (id) => {
      let u = this.uavs.find((x) => x.id === id);
      if (!u) { u = emptyUav(id ?? `uav${this.uavs.length + 1}`); this.uavs.push(u); }
      return u;
    };
    for (const f of doc.features ?? []) {
      const p = f.properties ?? {};
      const point = f.geometry?.type === "Point" ? [f.geometry.coordinates[1], f.geometry.coordinates[0]] : null;
      if (p.role === "area" && !this.area) this.area = f;
      else if (p.role === "no-fly") this.zones.push(f);
      else if (p.role === "start") {
        const u = uav(p.uav);
        const { role, uav: _, vehicle, speed_m_s: speed, ...more } = p;
        Object.assign(u, { startAt: point, vehicle: vehicle ?? null, speed: speed ?? u.speed, startProps: more });
      } else if (p.role === "goal") {
        const u = uav(p.uav);
        const { role, uav: _, speed_m_s: speed, ...more } = p;
        Object.assign(u, { goalAt: point, speed: u.speed ?? speed ?? null, goalProps: more });
      } else this.others.push(f);
    }
    if (!this.uavs.length) this.uavs.push(emptyUav("uav1"));
    this.render();
  }

  /** Everything drawn or imported, as [lat, lon] points (to fit the view on). */
  points() {
    const out = [];
    const walk = (c) => { if (typeof c[0] === "number") out.push([c[1], c[0]]); else c.forEach(walk); };
    for (const f of this.features().features) if (f.geometry) walk(f.geometry.coordinates);
    return out;
  }

  // --- the service -----------------------------------------------------------------------

  async submit() {
    this.clearRefusal();
    if (!this.area) { this.refuse("draw the area first (Click the map to: draw the area)"); return; }
    const { refs } = this.features();
    this.posted = refs;
    await this.post(JSON.stringify(this.collection()), GEOJSON);
  }

  async post(text, contentType) {
    $("geo-status").textContent = "deriving the grid…";
    try {
      const { data } = await postAs("/scenarios", text, contentType);
      const blocked = data.scenario.obstacles.length;
      const g = data.scenario.grid;
      $("geo-status").textContent = `grid ${g.width}×${g.height} of ${g.cell_size_m} m, ${blocked} cells blocked`;
      this.setTool("none");
      this.hooks.stored(data); // which loads the stored file back in here
    } catch (error) {
      $("geo-status").textContent = "refused";
      if (error instanceof ApiError && error.status === 422) this.refused422(error);
      else this.hooks.fail(error);
    }
  }

  refused422(error) {
    const detail = error.detail;
    const messages = Array.isArray(detail)
      ? detail.map((d) => `${(d.loc ?? []).filter((p) => p !== "body").join(".")}: ${String(d.msg).replace(/^Value error, /, "")}`)
      : [String(detail)];
    const index = /^features\[(\d+)\]/.exec(error.body?.feature ?? "")?.[1];
    this.refused = index == null ? null : this.posted[Number(index)] ?? null;
    this.refuse(...messages);
    this.render();
  }

  refuse(...messages) {
    $("geo-errors").replaceChildren(...messages.map((m) => node("span", { class: "field-error", text: m })));
    this.hooks.say(`the area is refused: ${messages[0]}`, "error");
  }

  clearRefusal() {
    this.refused = null;
    $("geo-errors").replaceChildren();
  }

  async importFile(file) {
    this.clearRefusal();
    const text = await file.text();
    const name = file.name.toLowerCase();
    if (name.endsWith(".plan")) { this.refuse(PLAN_FILES); return; }
    if (name.endsWith(".kml") || text.trimStart().startsWith("<")) {
      this.posted = [];
      await this.post(text, KML);
      return;
    }
    let doc;
    try { doc = JSON.parse(text); } catch (error) { this.refuse(`${file.name}: not JSON (${error.message})`); return; }
    if (doc?.fileType === "Plan") { this.refuse(PLAN_FILES); return; }
    if (doc?.type !== "FeatureCollection") { this.refuse(`${file.name}: not a GeoJSON FeatureCollection`); return; }
    this.load(doc);
    this.dirty = true; // not derived yet
    this.field.fitTo(this.points(), 50);
    this.hooks.say(`${file.name}: ${doc.features?.length ?? 0} features; Derive the grid to check and store it`);
  }

  // --- the panel -------------------------------------------------------------------------

  edited() {
    this.dirty = true;
    this.clearRefusal();
    $("geo-status").textContent = "edited: Derive the grid";
    this.render();
  }

  clear() {
    this.reset();
    this.field.setSketch(null);
    this.setTool("none");
    this.clearRefusal();
    $("geo-status").textContent = "";
    this.render();
    this.field.setGeo(null);
    this.dirty = false;
  }

  whereIs(vehicleId) {
    const v = this.hooks.vehicles().find((x) => x.id === vehicleId);
    return v?.live?.lat != null ? [v.live.lat, v.live.lon] : null;
  }

  /** Anything drawn, imported or being drawn (the view then stays where it is). */
  hasDrawing() {
    return Boolean(this.area || this.zones.length || this.sketch || this.others.length
      || this.uavs.some((u) => u.startAt || u.goalAt || u.vehicle));
  }

  /** The vehicle each UAV starts at, when it starts "where vehicle X is". */
  startVehicles() {
    return new Map(this.uavs.filter((u) => u.vehicle).map((u) => [u.id, u.vehicle]));
  }

  isRefused(ref) {
    return this.refused != null && ref != null && Object.entries(ref).every(([k, v]) => this.refused[k] === v);
  }

  render() {
    const { features, refs } = this.features();
    const order = (uav) => Math.max(0, this.uavs.findIndex((u) => u.id === uav));
    this.field.setGeo({ features }, order, (v) => this.whereIs(v), (i) => this.isRefused(refs[i]));
    const shapes = [];
    const remove = (label, onclick) => node("button", { type: "button", class: "small", text: "×", "aria-label": `remove ${label}`, onclick });
    const item = (label, ref, onRemove) => node("li", { "data-kind": ref.kind, "aria-invalid": this.isRefused(ref) ? "true" : null },
      label, " ", remove(label, onRemove));
    const corners = (f) => (f.geometry?.type === "Polygon" ? `${f.geometry.coordinates[0].length - 1} corners` : f.geometry?.type === "Point" ? `circle of ${f.properties.radius_m} m` : f.geometry?.type ?? "");
    if (this.area) shapes.push(item(`area: ${corners(this.area)}`, { kind: "area" }, () => { this.area = null; this.edited(); }));
    this.zones.forEach((z, i) => shapes.push(item(`no-fly ${z.properties.name ?? i + 1}: ${corners(z)}`, { kind: "zone", i },
      () => { this.zones.splice(i, 1); this.edited(); })));
    if (this.others.length) shapes.push(node("li", { class: "muted", text: `${this.others.length} more (rally points) kept from the file` }));
    $("geo-features").replaceChildren(...shapes);
    this.renderUavs();
  }

  renderUavs() {
    const vehicles = this.hooks.vehicles();
    this.vehicleIds = vehicles.map((v) => v.id).join(",");
    const body = $("geo-uav-table").querySelector("tbody");
    body.replaceChildren(...this.uavs.map((u, i) => {
      const bad = (kind) => (this.isRefused({ kind, i }) ? "true" : null);
      const start = node("select", { "aria-label": `where ${u.id} starts`, "data-uav": u.id, class: "geo-start-select",
        onchange: (e) => { u.vehicle = e.target.value || null; if (u.vehicle) u.startAt = null; this.edited(); } },
      node("option", { value: "", text: u.startAt ? "the point" : "click the map" }),
      ...vehicles.map((v) => node("option", { value: v.id, text: `at ${v.name} (${v.id})` })));
      start.value = u.vehicle ?? "";
      return node("tr", {},
        node("td", {}, node("input", { type: "radio", name: "geo-sel-uav", checked: i === this.selected, "aria-label": `select ${u.id}`,
          onchange: () => { this.selected = i; this.toolChanged(); } })),
        node("td", {}, node("span", { class: "swatch", style: `--c:${colourOf(i)}` }), node("input", {
          value: u.id, class: "narrow", "aria-label": `UAV ${i + 1} id`, onchange: (e) => { u.id = e.target.value.trim() || u.id; this.edited(); } })),
        node("td", { "aria-invalid": bad("start"), title: u.startAt ? u.startAt.map((c) => c.toFixed(6)).join(", ") : "" }, start),
        node("td", { "aria-invalid": bad("goal"), class: "geo-goal-cell", title: u.goalAt ? u.goalAt.map((c) => c.toFixed(6)).join(", ") : "",
          text: u.goalAt ? "set" : "–" }),
        node("td", {}, node("input", { type: "number", step: "any", min: "0", class: "narrow", value: u.speed ?? "", "aria-label": `${u.id} speed (m/s)`,
          onchange: (e) => { u.speed = e.target.value === "" ? null : Number(e.target.value); this.edited(); } })),
        node("td", {}, node("button", { type: "button", text: "×", "aria-label": `remove ${u.id}`, disabled: this.uavs.length <= 1,
          onclick: () => { this.uavs.splice(i, 1); this.selected = 0; this.edited(); } })));
    }));
  }

  /** The vehicles changed (registered, or first heard): the start choices follow. */
  vehiclesChanged() {
    const ids = this.hooks.vehicles().map((v) => v.id).join(",");
    if (ids === this.vehicleIds || $("geo-uav-table").contains(document.activeElement)) return;
    this.renderUavs();
    if (this.uavs.some((u) => u.vehicle)) this.render();
  }

  addUav() {
    const used = new Set(this.uavs.map((u) => u.id));
    let k = this.uavs.length + 1;
    while (used.has(`uav${k}`)) k++;
    this.uavs.push(emptyUav(`uav${k}`));
    this.selected = this.uavs.length - 1;
    this.render();
    this.toolChanged();
  }

  wire() {
    document.querySelectorAll('input[name="geo-tool"]').forEach((r) => r.addEventListener("change", () => this.toolChanged()));
    $("geo-close-btn").addEventListener("click", () => this.sketch && this.closeShape());
    $("geo-undo-btn").addEventListener("click", () => this.undoPoint());
    $("geo-cancel-btn").addEventListener("click", () => { this.cancelShape(); this.setTool("none"); });
    $("geo-add-uav-btn").addEventListener("click", () => this.addUav());
    $("geo-submit-btn").addEventListener("click", () => this.submit());
    $("geo-clear-btn").addEventListener("click", () => this.clear());
    $("geo-cell").addEventListener("change", () => this.edited());
    $("geo-file").addEventListener("change", async (e) => {
      const file = e.target.files?.[0];
      e.target.value = "";
      if (file) await this.importFile(file).catch((error) => this.hooks.fail(error));
    });
    document.addEventListener("keydown", (e) => {
      if (e.key === "Escape" && this.sketch) this.cancelShape();
    });
    this.drawSketch();
    this.renderUavs();
  }
}
