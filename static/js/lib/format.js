/* How times, counts and numbers are written on the page. Times are server times in seconds. */

export function formatTime(ts) {
  return new Date(ts * 1000).toLocaleTimeString();
}

export function formatDate(ts) {
  return new Date(ts * 1000).toLocaleString();
}

export function plural(count, word) {
  return `${count} ${word}${count === 1 ? "" : "s"}`;
}

/* A number with `digits` decimals, or nothing where a report has none. */
export function decimals(value, digits) {
  return value === null || value === undefined || value === "" || !Number.isFinite(Number(value))
    ? "" : Number(value).toFixed(digits);
}
