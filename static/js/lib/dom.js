/* Small DOM helpers every module uses. */

export const $ = (selector, root = document) => root.querySelector(selector);
export const $$ = (selector, root = document) => Array.from(root.querySelectorAll(selector));

export function escapeHtml(text) {
  return String(text).replace(/[&<>"']/g, (c) => ({
    "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
}

/* Plays a CSS animation again from its start, even while it is still running. */
export function replayAnimation(element, className) {
  element.classList.remove(className);
  void element.offsetWidth;  // A reflow between: otherwise the browser sees no change.
  element.classList.add(className);
}
