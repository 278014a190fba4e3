/* Small DOM helpers every module uses. */

export const $ = (selector, root = document) => root.querySelector(selector);
export const $$ = (selector, root = document) => Array.from(root.querySelectorAll(selector));

export function escapeHtml(text) {
  return String(text).replace(/[&<>"']/g, (c) => ({
    "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" }[c]));
}

/* Plays the CSS animation that className gives element again from its start, even while
   it is still running; the class comes off as it ends. Without forcing a layout (a class
   taken off and put back shows the browser no change unless it lays out between): on a
   wall of cameras alarming, those layouts took the page's main thread 2% of its time. */
export function replayAnimation(element, className) {
  const on = element.classList.contains(className);
  const running = on ? element.getAnimations().filter((a) => a instanceof CSSAnimation) : [];
  if (running.length) {
    for (const animation of running) animation.currentTime = 0;
    return;
  }
  takeOffAtEnd(element, className);
  if (!on) {
    element.classList.add(className);
    return;
  }
  // On, but its animation never ran (the element was not shown): again, with a frame's
  // style in between.
  element.classList.remove(className);
  requestAnimationFrame(() => element.classList.add(className));
}

const takenOffAtEnd = new WeakMap();  // element -> the classes its animations' ends take off

/* Once per element and class: the class comes off when element's own animation ends. */
function takeOffAtEnd(element, className) {
  const classes = takenOffAtEnd.get(element) ?? new Set();
  if (classes.has(className)) return;
  classes.add(className);
  takenOffAtEnd.set(element, classes);
  const ended = (event) => {
    if (event.target === element) element.classList.remove(className);  // not a child's
  };
  element.addEventListener("animationend", ended);
  element.addEventListener("animationcancel", ended);
}
