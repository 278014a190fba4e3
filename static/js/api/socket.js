/* /ws: the server's live messages. The connection is shown on a badge and made again when
   it drops (after 0.5 s, doubling up to 5 s); each message goes to its type's handler. */

const FIRST_RETRY_MS = 500;
const LAST_RETRY_MS = 5000;

/* A message's kind: its type, but "status" tells of a camera or of an analysis by the id
   it carries. */
function kindOf(message) {
  if (message.type !== "status") return message.type;
  if (message.camera_id !== undefined) return "camera_status";
  if (message.analysis_id !== undefined) return "analysis_status";
  return null;
}

export class ServerSocket {
  /* opened(reconnected) and closed() are told of the connection; handlers maps a
     message's kind (alarm, motion_end, camera_status, ...) to what it does. */
  constructor(badge, { opened, closed, handlers }) {
    this.badge = badge;
    this.onOpened = opened;
    this.onClosed = closed;
    this.handlers = handlers;
    this.state = "connecting";  // then "up", or "down" while the server is unreachable
    this.everUp = false;
    this.retryMs = FIRST_RETRY_MS;
  }

  connect() {
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    const socket = new WebSocket(`${scheme}://${location.host}/ws`);
    socket.onopen = () => this.opened();
    socket.onclose = () => this.closed();
    socket.onmessage = (event) => this.dispatch(event.data);
  }

  opened() {
    this.retryMs = FIRST_RETRY_MS;
    this.showBadge("live", "badge-live", "live connection to the server");
    const reconnected = this.everUp;
    this.state = "up";
    this.everUp = true;
    this.onOpened(reconnected);
  }

  closed() {
    this.showBadge("server unreachable", "badge-reconnecting", "no connection to the server: trying again");
    if (this.state !== "down") {
      this.state = "down";
      this.onClosed();
    }
    setTimeout(() => this.connect(), this.retryMs);
    this.retryMs = Math.min(this.retryMs * 2, LAST_RETRY_MS);
  }

  dispatch(data) {
    let message;
    try { message = JSON.parse(data); } catch (_) { return; }
    const kind = kindOf(message);
    if (Object.hasOwn(this.handlers, kind)) this.handlers[kind](message);
  }

  showBadge(text, className, title) {
    this.badge.textContent = text;
    this.badge.className = `badge ${className}`;
    this.badge.title = title;
  }
}
