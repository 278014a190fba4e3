/* The HTTP API: JSON in and out; a refusal becomes an Error in the server's own words. */

/* A 401 means the session has ended (or never began): log in, then come back here. */
export function toLogin() {
  location.assign(`/login?next=${encodeURIComponent(location.pathname + location.search)}`);
}

export async function api(method, url, body) {
  const options = { method, headers: {} };
  if (body !== undefined) {
    options.headers["Content-Type"] = "application/json";
    options.body = JSON.stringify(body);
  }
  let response;
  try {
    response = await fetch(url, options);
  } catch (_) {
    // No answer at all (server down, network gone): the browser's own words ("Failed to
    // fetch") tell a user nothing.
    throw new Error("Server unreachable: try again when it is back");
  }
  if (response.status === 401) {
    toLogin();
    throw new Error("logged out");
  }
  if (!response.ok) {
    let detail = response.statusText;
    try {
      const data = await response.json();
      detail = typeof data.detail === "string" ? data.detail
        : (data.detail || []).map((d) => d.msg).join("; ") || detail;
    } catch (_) { /* not JSON */ }
    throw new Error(detail);
  }
  return response.status === 204 ? null : response.json();
}
