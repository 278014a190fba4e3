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
  if (!element.classList.contains(className)) {
    const ended = (event) => {
      if (event.target !== element) return;  // a child's animation
      element.classList.remove(className);
      element.removeEventListener("animationend", ended);
      element.removeEventListener("animationcancel", ended);
    };
    element.addEventListener("animationend", ended);
    element.addEventListener("animationcancel", ended);
    element.classList.add(className);
    return;
  }
  const running = element.getAnimations().filter((animation) => animation instanceof CSSAnimation);
  if (running.length) {
    for (const animation of running) animation.currentTime = 0;
    return;
  }
  // The class is on, its animation never ran (the element was not shown): again, with a
  // frame's style in between.
  element.classList.remove(className);
  requestAnimationFrame(() => replayAnimation(element, className));
}
