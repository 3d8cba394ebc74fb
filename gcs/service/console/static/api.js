// The service's public API, same origin. Reading is open; a request that changes state
// carries the operator's token, asked once and kept in this tab's sessionStorage only.
const TOKEN_KEY = "mvo-gcs-token";

export class ApiError extends Error {
  constructor(status, detail, body = null) {
    super(typeof detail === "string" ? detail : `HTTP ${status}`);
    this.status = status;
    this.detail = detail;
    this.body = body; // the whole answer (a geographic 422 also names its `feature`)
  }
}

let asking = null;

/** The token, asking the operator in a dialog when there is none yet. */
export function token() {
  const kept = sessionStorage.getItem(TOKEN_KEY);
  if (kept) return Promise.resolve(kept);
  if (asking) return asking;
  const dialog = document.getElementById("token-dialog");
  const input = document.getElementById("token-input");
  asking = new Promise((resolve, reject) => {
    dialog.addEventListener("close", () => {
      asking = null;
      const value = input.value.trim();
      input.value = "";
      if (dialog.returnValue === "ok" && value) {
        sessionStorage.setItem(TOKEN_KEY, value);
        resolve(value);
      } else {
        reject(new ApiError(401, "no token given: this needs the operator's token"));
      }
    }, { once: true });
    dialog.showModal();
    input.focus();
  });
  return asking;
}

export function forgetToken() {
  sessionStorage.removeItem(TOKEN_KEY);
}

export function hasToken() {
  return Boolean(sessionStorage.getItem(TOKEN_KEY));
}

/** {status, data}; throws ApiError with the answer's `detail` on a 4xx or 5xx. A body is
 * sent as JSON, or as it is (a string) under `contentType` when one is given. */
export async function api(method, path, body, contentType = null) {
  for (let attempt = 0; ; attempt++) {
    const headers = { Accept: "application/json" };
    if (body !== undefined) headers["Content-Type"] = contentType ?? "application/json";
    if (method !== "GET") headers.Authorization = `Bearer ${await token()}`;
    const sent = body === undefined ? undefined : contentType ? body : JSON.stringify(body);
    const answer = await fetch(path, { method, headers, body: sent });
    if ((answer.status === 401 || answer.status === 403) && method !== "GET" && attempt === 0) {
      forgetToken(); // a wrong or stale token: ask again, once
      continue;
    }
    const text = answer.status === 204 ? "" : await answer.text();
    let data = null;
    try { data = text ? JSON.parse(text) : null; } catch { data = text; }
    if (!answer.ok) throw new ApiError(answer.status, data?.detail ?? answer.statusText, data);
    return { status: answer.status, data };
  }
}

export const get = (path) => api("GET", path).then((a) => a.data);
export const post = (path, body) => api("POST", path, body);
/** A document as it is (GeoJSON, KML) under its own media type. */
export const postAs = (path, text, contentType) => api("POST", path, text, contentType);

export function wsUrl(path) {
  return `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}${path}`;
}
