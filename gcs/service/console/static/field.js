// The field on the map: grid, scenario, plan paths, the animation, live vehicles.
// Leaflet (vendored, global L) draws in latitude/longitude; GridFrame converts cells.
import { GridFrame } from "./geo.js";

// Okabe-Ito: distinguishable with the common colour-vision deficiencies. Paths also differ
// in dash pattern and carry their UAV's id, so colour is never the only cue.
export const COLOURS = ["#0072B2", "#E69F00", "#009E73", "#CC79A7", "#D55E00", "#56B4E9",
  "#000000", "#F0E442"];
const DASHES = [null, "8 4", "2 4", "10 3 2 3"];
const TRAIL_POINTS = 600;

export function colourOf(i) { return COLOURS[i % COLOURS.length]; }
function dashOf(i) { return DASHES[Math.floor(i / COLOURS.length + i) % DASHES.length]; }

/** Where a piecewise-linear [t, x, y] trajectory is at time t (clamped to its ends). */
export function positionAt(trajectory, t) {
  if (t <= trajectory[0][0]) return [trajectory[0][1], trajectory[0][2]];
  for (let i = 1; i < trajectory.length; i++) {
    const [t1, x1, y1] = trajectory[i];
    if (t <= t1) {
      const [t0, x0, y0] = trajectory[i - 1];
      const f = t1 > t0 ? (t - t0) / (t1 - t0) : 1;
      return [x0 + f * (x1 - x0), y0 + f * (y1 - y0)];
    }
  }
  const last = trajectory[trajectory.length - 1];
  return [last[1], last[2]];
}

function escape(text) {
  return String(text).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

function northArrow() {
  const control = L.control({ position: "topright" });
  control.onAdd = () => {
    const div = L.DomUtil.create("div", "north-arrow");
    div.setAttribute("aria-label", "north is up");
    div.innerHTML = '<svg viewBox="0 0 24 36" width="24" height="36" aria-hidden="true">'
      + '<path d="M12 2 L20 22 L12 17 L4 22 Z" fill="#222"/>'
      + '<text x="12" y="34" text-anchor="middle" font-size="11" font-weight="bold">N</text></svg>';
    return div;
  };
  return control;
}

export class FieldMap {
  constructor(element, tileUrl) {
    this.map = L.map(element, {
      zoomSnap: 0.25, maxZoom: 24, minZoom: 2, attributionControl: Boolean(tileUrl),
    });
    this.map.setView([0, 0], 3);
    if (tileUrl) {
      L.tileLayer(tileUrl, {
        maxZoom: 24, maxNativeZoom: 19, attribution: `tiles: ${escape(new URL(tileUrl.replace(/[{}]/g, ""), location.href).host)}`,
      }).addTo(this.map);
    } else {
      element.classList.add("offline");
    }
    L.control.scale({ imperial: false, maxWidth: 160 }).addTo(this.map);
    northArrow().addTo(this.map);
    // Panes below the paths (overlayPane, 400): the grid's cells, then the area and its
    // zones over them; the shape being drawn above everything.
    for (const [pane, z] of [["cells", 380], ["geo", 390], ["sketch", 450]]) {
      this.map.createPane(pane).style.zIndex = String(z);
    }
    this.layers = {};
    for (const name of ["grid", "scenario", "geo", "plan", "flown", "anim", "objects", "parked", "sketch", "vehicles"]) {
      this.layers[name] = L.layerGroup().addTo(this.map);
    }
    this.frame = null;
    this.vehicles = new Map(); // uav id -> {marker, trail}
    this.parked = new Map(); // vehicle id -> marker, for vehicles not in a flight
    this.onCell = null;
    this.onMapClick = null; // (latlng) => true when it took the click (drawing the area)
    this.onMapDblClick = null;
    this.map.on("dblclick", (e) => this.onMapDblClick?.(e.latlng));
    this.map.on("click", (e) => {
      if (this.onMapClick?.(e.latlng)) return;
      if (!this.frame || !this.onCell) return;
      const [x, y] = this.frame.toCells(e.latlng.lat, e.latlng.lng);
      const cell = [Math.round(x), Math.round(y)];
      if (cell[0] >= 0 && cell[1] >= 0 && cell[0] < this.width && cell[1] < this.height) {
        this.onCell(cell);
      }
    });
  }

  ll(x, y) { return this.frame.toLatLng(x, y); }

  /** Centre the view on these [lat, lon] with room around them (at least minSpanM across):
   * where the vehicles are, before any scenario is loaded. */
  fitTo(latlngs, minSpanM = 200) {
    if (!latlngs.length) return;
    const bounds = L.latLngBounds(latlngs).pad(0.5);
    const c = bounds.getCenter();
    const dLat = minSpanM / 2 / 111320;
    const dLon = dLat / Math.max(Math.cos(c.lat * Math.PI / 180), 0.01);
    bounds.extend([[c.lat - dLat, c.lng - dLon], [c.lat + dLat, c.lng + dLon]]);
    this.map.fitBounds(bounds, { animate: false });
  }

  /** Drawing a shape: a double click closes it instead of zooming. */
  setDrawing(on) {
    if (on) this.map.doubleClickZoom.disable(); else this.map.doubleClickZoom.enable();
    this.map.getContainer().classList.toggle("drawing", on);
  }

  /** Registered vehicles not in a flight, where they last reported: {id, name, lat, lon,
   * online}. A flight's live vehicles are drawn by updateVehicles instead. */
  showParked(vehicles) {
    const seen = new Set();
    for (const v of vehicles) {
      if (v.lat == null || v.lon == null) continue;
      seen.add(v.id);
      let marker = this.parked.get(v.id);
      if (!marker) {
        const html = `<div class="parked-vehicle" data-vehicle="${escape(v.id)}">`
          + '<svg viewBox="-6 -6 12 12" width="12" height="12" aria-hidden="true"><circle r="4.5" fill="#20262e" stroke="#fff" stroke-width="1.5"/></svg>'
          + `<span class="vehicle-label">${escape(v.name ?? v.id)}</span></div>`;
        marker = L.marker([v.lat, v.lon], { // under the starts and goals drawn on it
          icon: L.divIcon({ className: "parked-icon", html, iconSize: [12, 12], iconAnchor: [6, 6] }),
          interactive: false, keyboard: false, zIndexOffset: -1000,
        }).addTo(this.layers.parked);
        this.parked.set(v.id, marker);
      }
      marker.setLatLng([v.lat, v.lon]);
      const el = marker.getElement()?.querySelector(".parked-vehicle");
      if (el) {
        el.dataset.lat = v.lat; el.dataset.lon = v.lon;
        el.classList.toggle("offline", !v.online);
        el.title = `${v.name ?? v.id} (vehicle ${v.id})${v.online ? "" : ", not heard"}`;
      }
    }
    for (const [id, marker] of this.parked) {
      if (!seen.has(id)) { marker.remove(); this.parked.delete(id); }
    }
  }

  /** A geographic scenario's features over the map: the area's outline, the no-fly zones,
   * starts (S) and goals (G) per UAV, rally points. `whereIs(vehicleId)` places a start
   * "where vehicle X is" that has no position yet; `refused(index)` marks the feature a
   * 422 named. */
  setGeo(collection, uavIndex = () => 0, whereIs = () => null, refused = () => false) {
    const layer = this.layers.geo;
    layer.clearLayers();
    for (const [i, f] of (collection?.features ?? []).entries()) {
      const p = f.properties ?? {};
      const g = f.geometry;
      const bad = refused(i) ? " geo-refused" : "";
      if (p.role === "area" || p.role === "no-fly") {
        const className = `${p.role === "area" ? "geo-area" : "geo-zone"}${bad}`;
        const ring = (r) => r.map(([lon, lat]) => [lat, lon]);
        const style = { className, weight: 2, interactive: false, pane: "geo" };
        let shape = null;
        if (g?.type === "Polygon") shape = L.polygon(g.coordinates.map(ring), style);
        else if (g?.type === "MultiPolygon") shape = L.polygon(g.coordinates.map((poly) => poly.map(ring)), style);
        else if (g?.type === "Point" && p.radius_m) {
          shape = L.circle([g.coordinates[1], g.coordinates[0]], { ...style, radius: p.radius_m });
        }
        shape?.addTo(layer).getElement()?.setAttribute("data-feature", String(i));
      } else if (p.role === "start" || p.role === "goal") {
        const at = g?.type === "Point" ? [g.coordinates[1], g.coordinates[0]] : whereIs(p.vehicle);
        if (!at) continue;
        const k = uavIndex(p.uav);
        const text = `${p.role === "start" ? "S" : "G"} ${p.uav ?? "?"}`;
        const html = `<div class="geo-${p.role}${bad}" data-uav="${escape(p.uav ?? "")}" data-feature="${i}"`
          + ` style="--c:${colourOf(k)}"><span>${escape(text)}</span></div>`;
        L.marker(at, {
          icon: L.divIcon({ className: "geo-end", html, iconSize: [12, 12], iconAnchor: [6, 6] }),
          interactive: false, keyboard: false,
        }).addTo(layer);
      } else if (p.role === "rally" && g?.type === "Point") {
        this.label(layer, null, null, "R", "geo-rally", [g.coordinates[1], g.coordinates[0]]);
      }
    }
  }

  /** The shape being drawn: its points so far. */
  setSketch(latlngs) {
    const layer = this.layers.sketch;
    layer.clearLayers();
    if (!latlngs?.length) return;
    L.polyline(latlngs, { className: "sketch", weight: 2, dashArray: "6 4", interactive: false, pane: "sketch" }).addTo(layer);
    for (const p of latlngs) {
      L.circleMarker(p, { radius: 4, className: "sketch-vertex", weight: 2, interactive: false, pane: "sketch" }).addTo(layer);
    }
  }

  square(x, y, half = 0.5) {
    return [this.ll(x - half, y - half), this.ll(x + half, y - half),
      this.ll(x + half, y + half), this.ll(x - half, y + half)];
  }

  /** Draw the grid, obstacles, objects, starts and goals; `fit` recentres the view. */
  setScenario(scenario, uavIndex, fit) {
    const origin = scenario.origin ?? { lat: 0, lon: 0, alt_m: 0 }; // planning only
    const g = scenario.grid;
    const changed = !this.frame || this.width !== g.width || this.height !== g.height
      || this.frame.lat0 !== origin.lat || this.frame.lon0 !== origin.lon
      || this.frame.cell !== (g.cell_size_m ?? 10);
    this.frame = new GridFrame(origin, g.cell_size_m ?? 10);
    this.width = g.width;
    this.height = g.height;
    const grid = this.layers.grid;
    grid.clearLayers();
    const lines = [];
    for (let x = 0; x <= g.width; x++) lines.push([this.ll(x - 0.5, -0.5), this.ll(x - 0.5, g.height - 0.5)]);
    for (let y = 0; y <= g.height; y++) lines.push([this.ll(-0.5, y - 0.5), this.ll(g.width - 0.5, y - 0.5)]);
    L.polyline(lines, { className: "grid-line", weight: 1, interactive: false, pane: "cells" }).addTo(grid);
    const step = Math.max(1, Math.ceil(Math.max(g.width, g.height) / 20));
    for (let x = 0; x < g.width; x += step) this.label(grid, x, -0.9, String(x), "axis-label");
    for (let y = 0; y < g.height; y += step) this.label(grid, -0.9, y, String(y), "axis-label");

    const layer = this.layers.scenario;
    layer.clearLayers();
    for (const [x, y] of scenario.obstacles ?? []) {
      L.polygon(this.square(x, y), { className: "obstacle", weight: 1, interactive: false, pane: "cells" }).addTo(layer);
    }
    const objects = Array.isArray(scenario.non_uav_objects) ? scenario.non_uav_objects : [];
    for (const [x, y] of objects) this.object(layer, x, y, "object");
    scenario.uavs.forEach((u, i) => {
      this.endpoint(layer, u.start, `S${i + 1}`, "cell-start", u.id, i);
      this.endpoint(layer, u.goal, `G${i + 1}`, "cell-goal", u.id, i);
    });
    if (fit || changed) {
      this.map.fitBounds(L.latLngBounds([this.ll(-1, -1), this.ll(g.width, g.height)]), { animate: false });
    }
  }

  label(layer, x, y, text, className, at = null) {
    L.marker(at ?? this.ll(x, y), {
      icon: L.divIcon({ className, html: escape(text), iconSize: [24, 14], iconAnchor: [12, 7] }),
      interactive: false, keyboard: false,
    }).addTo(layer);
  }

  endpoint(layer, cell, text, className, uav, i) {
    const html = `<div class="${className}" data-uav="${escape(uav)}" data-cell="${cell[0]},${cell[1]}"`
      + ` style="--c:${colourOf(i)}">${escape(text)}</div>`;
    L.marker(this.ll(cell[0], cell[1]), {
      icon: L.divIcon({ className: "endpoint", html, iconSize: [22, 22], iconAnchor: [11, 11] }),
      interactive: false, keyboard: false,
    }).addTo(layer);
  }

  object(layer, x, y, className) {
    const html = `<div class="${className}" data-cell="${x},${y}" title="non-UAV object at ${x}, ${y}">`
      + '<svg viewBox="0 0 24 24" width="22" height="22" aria-hidden="true"><path d="M2 12 Q7 6 12 12 Q17 6 22 12" '
      + 'fill="none" stroke="currentColor" stroke-width="2.5"/></svg></div>';
    L.marker(this.ll(x, y), {
      icon: L.divIcon({ className: "object-icon", html, iconSize: [22, 22], iconAnchor: [11, 11] }),
      interactive: false, keyboard: false,
    }).addTo(layer);
  }

  /** A reported object: drawn on its cell above the plan. */
  reportedObject(cell) {
    L.polygon(this.square(cell[0], cell[1], 0.45), { className: "reported-cell", weight: 2, interactive: false })
      .addTo(this.layers.objects);
    this.object(this.layers.objects, cell[0], cell[1], "object reported");
  }

  clearReported() { this.layers.objects.clearLayers(); }

  /** Objects the planner placed (a scenario's `{"random": K}`), drawn with the plan. */
  planObjects(cells) {
    for (const [x, y] of cells) this.object(this.layers.plan, x, y, "object");
  }

  /** Each UAV's path in its colour; the `replanned` ones (their new path, from the live
   * replan's answer) marked as such. `wgs84` (the plan's `trajectories_wgs84`, [t, lat,
   * lon] per UAV) is drawn as it is; a replanned path comes in cells. */
  setPlan(plan, order, cellSize, radii, replanned = new Set(), wgs84 = null) {
    const layer = this.layers.plan;
    layer.clearLayers();
    this.plan = plan;
    this.order = order;
    this.cellSize = cellSize;
    if (!plan) { this.layers.anim.clearLayers(); this.discs = null; return; }
    plan.uavs.forEach((u) => {
      const i = order(u.id);
      const changed = replanned.has(u.id);
      const inWgs84 = !changed && wgs84?.[u.id];
      const points = inWgs84 ? inWgs84.map(([, lat, lon]) => [lat, lon]) : u.trajectory.map(([, x, y]) => this.ll(x, y));
      L.polyline(points, {
        color: colourOf(i), weight: changed ? 4 : 3, opacity: 0.9, dashArray: dashOf(i),
        interactive: false, className: `plan-path${changed ? " replanned" : ""}`,
      }).addTo(layer).getElement()?.setAttribute("data-uav", u.id);
      const [, gx, gy] = u.trajectory[u.trajectory.length - 1];
      if (changed) this.label(layer, gx, gy + 0.6, `${u.id} replanned`, "replan-label");
    });
    this.discs = new Map();
    const anim = this.layers.anim;
    anim.clearLayers();
    plan.uavs.forEach((u) => {
      const i = order(u.id);
      const radius = (radii.get(u.id) ?? 0.3) * cellSize;
      const disc = L.circle(this.ll(u.trajectory[0][1], u.trajectory[0][2]), {
        radius, color: colourOf(i), fillColor: colourOf(i), fillOpacity: 0.45, weight: 2,
        className: "anim-disc", interactive: false,
      }).addTo(anim);
      const tag = L.marker(disc.getLatLng(), {
        icon: L.divIcon({ className: "disc-label", html: escape(u.id), iconSize: [40, 14], iconAnchor: [-6, 18] }),
        interactive: false, keyboard: false,
      }).addTo(anim);
      this.discs.set(u.id, { disc, tag });
    });
  }

  /** Move the animation discs to plan time t. */
  showTime(t) {
    if (!this.plan || !this.discs) return;
    for (const u of this.plan.uavs) {
      const [x, y] = positionAt(u.trajectory, t);
      const { disc, tag } = this.discs.get(u.id);
      const at = this.ll(x, y);
      disc.setLatLng(at);
      tag.setLatLng(at);
    }
  }

  /** Live vehicles: a heading arrow per UAV with its trail. */
  updateVehicles(vehicles, order) {
    for (const v of vehicles) {
      const parked = this.parked.get(v.vehicle_id);
      if (parked) { parked.remove(); this.parked.delete(v.vehicle_id); } // flying now
      if (v.lat == null || v.lon == null) continue;
      const i = order(v.uav_id);
      let entry = this.vehicles.get(v.uav_id);
      if (!entry) {
        const html = `<div class="vehicle" data-uav="${escape(v.uav_id)}" style="--c:${colourOf(i)}">`
          + '<svg viewBox="-14 -14 28 28" width="28" height="28" aria-hidden="true">'
          + '<path d="M0 -12 L8 10 L0 5 L-8 10 Z" fill="var(--c)" stroke="#fff" stroke-width="1.5"/></svg>'
          + `<span class="vehicle-label">${escape(v.uav_id)}</span></div>`;
        const marker = L.marker([v.lat, v.lon], {
          icon: L.divIcon({ className: "vehicle-icon", html, iconSize: [28, 28], iconAnchor: [14, 14] }),
          keyboard: false, zIndexOffset: 1000,
        }).addTo(this.layers.vehicles);
        const trail = L.polyline([], {
          color: colourOf(i), weight: 2, opacity: 0.8, dashArray: "1 4", className: "trail", interactive: false,
        }).addTo(this.layers.flown);
        entry = { marker, trail };
        this.vehicles.set(v.uav_id, entry);
      }
      entry.marker.setLatLng([v.lat, v.lon]);
      const svg = entry.marker.getElement()?.querySelector("svg");
      if (svg) svg.style.transform = `rotate(${v.heading_deg ?? 0}deg)`;
      const el = entry.marker.getElement()?.querySelector(".vehicle");
      if (el) {
        el.dataset.lat = v.lat; el.dataset.lon = v.lon;
        el.classList.toggle("offline", v.online === false);
        el.title = `${v.uav_id}: ${v.mode ?? "?"}, ${v.relative_alt_m?.toFixed?.(1) ?? "?"} m`;
      }
      const points = entry.trail.getLatLngs();
      const last = points[points.length - 1];
      if (!last || last.lat !== v.lat || last.lng !== v.lon) {
        entry.trail.addLatLng([v.lat, v.lon]);
        if (points.length > TRAIL_POINTS) entry.trail.setLatLngs(points.slice(-TRAIL_POINTS));
      }
    }
  }

  clearVehicles() {
    this.layers.vehicles.clearLayers();
    this.layers.flown.clearLayers();
    this.vehicles.clear();
  }

  /** A UAV's flown track (look back), from the positions the service stored. */
  flownTrack(i, latlngs) {
    return L.polyline(latlngs, {
      color: colourOf(i), weight: 2, opacity: 0.9, className: "flown-track", interactive: false,
    }).addTo(this.layers.flown);
  }

  /** Stored points a UAV reached (look back): small rings in its colour. */
  reachedPoints(uav, i, latlngs) {
    const line = L.polyline(latlngs, {
      color: colourOf(i), weight: 2, dashArray: "1 4", className: "trail", interactive: false,
    }).addTo(this.layers.flown);
    for (const p of latlngs) {
      L.circleMarker(p, { radius: 4, color: colourOf(i), weight: 2, fillOpacity: 0, className: "reached", interactive: false })
        .addTo(this.layers.flown);
    }
    return line;
  }
}
