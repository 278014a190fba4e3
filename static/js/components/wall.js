/* The wall: every camera's live picture and name filling the window, nothing else, in a
   grid as square as the count allows (16 cameras: 4 x 4). The Wall button shows it and
   leaves it; /#wall opens the page on it (a wall display's bookmark). Only cameras on
   screen are sent over /ws/live, so the normal page shows a few at a time and the wall
   all of them. */

export class Wall {
  constructor(button, grid) {
    this.button = button;
    this.grid = grid;
    button.addEventListener("click", () => this.show(!this.on));
    window.addEventListener("hashchange", () => this.show(location.hash === "#wall"));
    this.show(location.hash === "#wall");
  }

  get on() {
    return document.body.classList.contains("wall");
  }

  show(on) {
    document.body.classList.toggle("wall", on);
    this.button.setAttribute("aria-pressed", String(on));
    this.button.textContent = on ? "Leave wall" : "Wall";
    // The address says #wall while it is shown (a reload keeps it); any other hash (a
    // section's, from the nav links) is left as it is.
    const hash = on ? "#wall" : "";
    if (on !== (location.hash === "#wall")) {
      history.replaceState(null, "", `${location.pathname}${location.search}${hash}`);
    }
    this.layout();
  }

  /* Columns and rows for the cards there are now. */
  layout() {
    const count = Math.max(1, this.grid.children.length);
    const columns = Math.ceil(Math.sqrt(count));
    this.grid.style.setProperty("--wall-columns", columns);
    this.grid.style.setProperty("--wall-rows", Math.ceil(count / columns));
  }
}
