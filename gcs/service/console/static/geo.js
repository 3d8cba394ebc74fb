// Grid cells <-> WGS84, as gcs/mission/geodesy.py does it with pymap3d: cell (x, y) is
// x·cell_size_m east and y·cell_size_m north of the origin on its local tangent plane.
const A = 6378137.0;
const F = 1 / 298.257223563;
const E2 = F * (2 - F);
const RAD = Math.PI / 180;

function toEcef(lat, lon, h) {
  const p = lat * RAD, l = lon * RAD;
  const n = A / Math.sqrt(1 - E2 * Math.sin(p) ** 2);
  return [(n + h) * Math.cos(p) * Math.cos(l), (n + h) * Math.cos(p) * Math.sin(l),
    (n * (1 - E2) + h) * Math.sin(p)];
}

function fromEcef(x, y, z) {
  const lon = Math.atan2(y, x);
  const p = Math.hypot(x, y);
  let lat = Math.atan2(z, p * (1 - E2));
  for (let i = 0; i < 6; i++) {
    const n = A / Math.sqrt(1 - E2 * Math.sin(lat) ** 2);
    const h = p / Math.cos(lat) - n;
    lat = Math.atan2(z, p * (1 - E2 * n / (n + h)));
  }
  return [lat / RAD, lon / RAD];
}

export class GridFrame {
  constructor(origin, cellSize) {
    this.lat0 = origin.lat;
    this.lon0 = origin.lon;
    this.alt0 = origin.alt_m ?? 0;
    this.cell = cellSize;
    this.ecef0 = toEcef(this.lat0, this.lon0, this.alt0);
    const p = this.lat0 * RAD, l = this.lon0 * RAD;
    this.sp = Math.sin(p); this.cp = Math.cos(p); this.sl = Math.sin(l); this.cl = Math.cos(l);
  }

  /** [lat, lon] of a grid position (fractional cells allowed). */
  toLatLng(x, y) {
    const e = x * this.cell, n = y * this.cell;
    const { sp, cp, sl, cl } = this;
    const dx = -sl * e - sp * cl * n, dy = cl * e - sp * sl * n, dz = cp * n;
    return fromEcef(this.ecef0[0] + dx, this.ecef0[1] + dy, this.ecef0[2] + dz);
  }

  /** [x, y] in cells of a latitude and longitude, taken at the origin's altitude. */
  toCells(lat, lon) {
    const [x, y, z] = toEcef(lat, lon, this.alt0);
    const dx = x - this.ecef0[0], dy = y - this.ecef0[1], dz = z - this.ecef0[2];
    const { sp, cp, sl, cl } = this;
    const e = -sl * dx + cl * dy;
    const n = -sp * cl * dx - sp * sl * dy + cp * dz;
    return [e / this.cell, n / this.cell];
  }
}
