"""What the forkserver that camera processes are forked from imports, once.

Imported there only (``CameraProcess.start``). A spawned camera process imported numpy,
OpenCV and the detector anew: about a second of CPU at every start, and at every restart
after a crash. Forked from a process that holds them, it starts at once.
"""

import signal

import app.workers.camera_host  # noqa: F401  # What every camera process runs.

# A SIGTERM to the server's process group (systemd, `timeout`) reaches the forkserver
# too. It must outlive the camera processes, to tell the server how each one exited; it
# exits by itself once the server is gone. (A camera process sets its own handler.)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
