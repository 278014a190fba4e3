/* Snapshot pictures, as the gallery, the alarm list and the toasts show them. */

export function snapshotUrl(id) {
  return `/api/snapshots/${id}.jpg`;
}

/* The snapshot id in a picture's URL, or NaN for any other picture. */
export function snapshotIdOf(url) {
  return Number(/^\/api\/snapshots\/(\d+)\.jpg$/.exec(url)?.[1]);
}

/* Whether the server, asked again, says the snapshot is gone (not merely unreachable). */
export async function snapshotDeleted(url) {
  try {
    return (await fetch(url, { cache: "no-store" })).status === 404;
  } catch (_) {
    return false;
  }
}
