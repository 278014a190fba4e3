/* The MQTT badge in the top bar, as /api/health tells it: hidden when Vigil has no broker
   (VIGIL_MQTT_URL unset), "MQTT" while connected to it, "MQTT down" with the reason in
   its title while not. A broker that is down costs MQTT only, so this is the one place
   the page shows it. */
import { api } from "../api/client.js";

const POLL_MS = 5000;

export class MqttBadge {
  constructor(badge) {
    this.badge = badge;
  }

  start() {
    this.refresh();
    setInterval(() => { if (!document.hidden) this.refresh(); }, POLL_MS);
  }

  async refresh() {
    let health;
    try {
      health = await api("GET", "/api/health");
    } catch (_) {
      return;  // The server itself is away: the connection badge says so.
    }
    this.show(health.mqtt);
  }

  show(mqtt) {
    const badge = this.badge;
    if (!mqtt || mqtt.state === "disabled") {
      badge.hidden = true;
      return;
    }
    const up = mqtt.state === "connected";
    badge.hidden = false;
    badge.dataset.state = mqtt.state;
    badge.className = `badge ${up ? "badge-live" : "badge-error"}`;
    badge.textContent = up ? "MQTT" : "MQTT down";
    badge.title = up
      ? `MQTT: connected to ${mqtt.broker}`
      : `MQTT: not connected to ${mqtt.broker}: ${mqtt.reason}`;
  }
}
