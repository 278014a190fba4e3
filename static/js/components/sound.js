/* The alarm sound and its button (on, muted, or waiting for a click to be allowed).

   Browsers let a page play sound only once the user has clicked or typed on it (the
   autoplay policy). Until then the sound button says "click to enable sound"; the first
   click or key press anywhere on the page unlocks it. */
import { $, replayAnimation } from "../lib/dom.js";

const MUTED_KEY = "vigil.muted";

export class AlarmSound {
  constructor(button) {
    this.button = button;
    this.muted = localStorage.getItem(MUTED_KEY) === "1";
    this.audio = null;
    /* Whether the press under way (the last pointerdown or key press on the page) began
       on the button while it asked to enable sound: the click that press ends in enables
       sound and does not mute. Every new press decides afresh, so a Tab away from the
       button or a press dragged off it leaves nothing behind for the next click. */
    this.pressUnlocks = false;
    const notePress = (event) => this.notePress(event);
    document.addEventListener("pointerdown", notePress, { capture: true });
    document.addEventListener("keydown", notePress, { capture: true });
    for (const type of ["pointerdown", "keydown", "touchend"]) {
      document.addEventListener(type, () => this.unlock(), { capture: true });
    }
    button.addEventListener("click", () => this.toggleMute());
    this.render();
  }

  ready() {
    return Boolean(this.audio && this.audio.state === "running");
  }

  locked() {
    return !this.muted && Boolean(window.AudioContext) && !this.ready();
  }

  notePress(event) {
    // Enter and Space are the keys that click a focused button.
    const activates = event.type === "pointerdown" || event.key === "Enter" || event.key === " ";
    this.pressUnlocks = activates && this.button.contains(event.target) && this.locked();
  }

  unlock() {
    if (!window.AudioContext || this.ready()) return;
    if (!this.audio) {
      this.audio = new AudioContext();
      this.audio.addEventListener("statechange", () => this.render());
    }
    this.audio.resume().then(() => this.render(), () => {});
    this.render();
  }

  toggleMute() {
    if (this.pressUnlocks) {
      this.pressUnlocks = false;
      return;
    }
    this.muted = !this.muted;
    localStorage.setItem(MUTED_KEY, this.muted ? "1" : "0");
    this.render();
  }

  beep() {
    if (this.muted) return;
    if (!this.ready()) {
      replayAnimation(this.button, "nudge");  // No sound yet: the eye to the button that enables it.
      return;
    }
    const now = this.audio.currentTime;
    for (const [offset, freq] of [[0, 880], [0.18, 660]]) {
      const osc = this.audio.createOscillator();
      const gain = this.audio.createGain();
      osc.type = "square";
      osc.frequency.value = freq;
      gain.gain.setValueAtTime(0.08, now + offset);
      gain.gain.exponentialRampToValueAtTime(0.0001, now + offset + 0.15);
      osc.connect(gain).connect(this.audio.destination);
      osc.start(now + offset);
      osc.stop(now + offset + 0.16);
    }
  }

  render() {
    const locked = this.locked();
    $(".label", this.button).textContent = this.muted ? "Sound off" : locked ? "Click to enable sound" : "Sound on";
    this.button.classList.toggle("locked", locked);
    this.button.setAttribute("aria-pressed", String(this.muted));
    this.button.title = locked ? "the browser plays sound only after a click or a key press on the page"
      : this.muted ? "alarm sound is off: click to turn it on" : "alarm sound is on: click to mute";
  }
}
