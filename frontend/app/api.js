// The API client: bearer token in sessionStorage (gone with the tab), JSON in and out, errors people can read.
import { loginHash } from "./state.js";

const TOKEN_KEY = "quasitune.token";

export class ApiError extends Error {
  constructor(status, detail, body) {
    super(detail);
    this.status = status;
    this.body = body;
  }
}

export function token() {
  return sessionStorage.getItem(TOKEN_KEY);
}

export function signOut() {
  sessionStorage.removeItem(TOKEN_KEY);
}

export async function signIn(username, password) {
  const form = new URLSearchParams({ username, password });
  const r = await fetch("/api/auth/token", { method: "POST", body: form });
  const body = await r.json().catch(() => ({}));
  if (!r.ok) throw new ApiError(r.status, body.detail || `sign-in failed (${r.status})`, body);
  sessionStorage.setItem(TOKEN_KEY, body.access_token);
  return body;
}

export async function api(path, { method = "GET", body } = {}) {
  const headers = { Authorization: `Bearer ${token()}` };
  if (body !== undefined) headers["Content-Type"] = "application/json";
  const r = await fetch(path, { method, headers, body: body === undefined ? undefined : JSON.stringify(body) });
  const data = await r.json().catch(() => ({}));
  if (!r.ok) {
    if (r.status === 401) {
      signOut();
      location.hash = loginHash();   // back to this page after signing in again
    }
    throw new ApiError(r.status, data.detail || `${method} ${path} failed (${r.status})`, data);
  }
  return data;
}

export const get = (path) => api(path);
export const post = (path, body = {}) => api(path, { method: "POST", body });
export const put = (path, body = {}) => api(path, { method: "PUT", body });
export const patch = (path, body = {}) => api(path, { method: "PATCH", body });
export const del = (path) => api(path, { method: "DELETE" });
