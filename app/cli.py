"""Command line: `vigil serve`, `vigil analyze`, `vigil evaluate` (`python -m app` is the same)."""

from __future__ import annotations

import argparse
import errno
import ipaddress
import json
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from app import __version__

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr (exit 2), like bad input."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def _sensitivity(value: str) -> float | None:
    if value.lower() == "auto":
        return None
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {value!r}") from None
    if not 1 <= number <= 255:
        raise argparse.ArgumentTypeError("sensitivity is a grey-level threshold from 1 to 255")
    return number


def _number(value: str) -> float:
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {value!r}") from None
    if not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"not a finite number: {value!r}")
    return number


def _non_negative(value: str) -> float:
    number = _number(value)
    if number < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, not {value}")
    return number


def _fps(value: str) -> float:
    from app.sources.files import MAX_FPS, valid_fps

    number = _number(value)
    if not valid_fps(number):
        raise argparse.ArgumentTypeError(
            f"must be a positive number of frames per second, at most {MAX_FPS:g}, not {value}"
        )
    return number


def _path(value: str) -> Path:
    # An empty one is the current folder to Path: outputs would land among the user's files.
    if not value.strip():
        raise argparse.ArgumentTypeError("an empty path")
    return Path(value)


def _detect_width(value: str) -> int:
    from app.vision.pipeline import check_detect_width

    try:
        width = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number of pixels: {value!r}") from None
    try:
        return check_detect_width(width)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"the detection width {exc}") from None


def _port(value: str) -> int:
    from app.core.config import MAX_PORT

    try:
        port = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {value!r}") from None
    if not 1 <= port <= MAX_PORT:
        raise argparse.ArgumentTypeError(f"port must be 1..{MAX_PORT}, not {port}")
    return port


def build_parser() -> argparse.ArgumentParser:
    from app.vision.motion import DEFAULT_METHOD, METHODS
    from app.vision.pipeline import MAX_DETECT_WIDTH, MIN_DETECT_WIDTH
    from app.vision.preprocess import DENOISE_METHODS, ENHANCE_METHODS

    parser = _Parser(prog="vigil", description="Vigil: tell me, and show me, when something moves.")
    parser.add_argument("--version", action="version", version=f"vigil {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    serve = commands.add_parser("serve", help="run the dashboard")
    serve.add_argument("--host", default=None, help="address to bind (default 127.0.0.1)")
    serve.add_argument("--port", type=_port, default=None, help="port (default 8000)")
    serve.add_argument(
        "--data", type=_path, default=None, help="folder for the database and snapshots"
    )

    analyze = commands.add_parser("analyze", help="analyse a recorded video offline")
    analyze.add_argument(
        "input", type=_path, help="a video file or a folder of frames (by name, 2 before 10)"
    )
    analyze.add_argument(
        "--out", type=_path, default=None, help="output folder (default: ./vigil-out/<input name>)"
    )
    analyze.add_argument(
        "--method",
        default=DEFAULT_METHOD,
        choices=sorted(METHODS),
        help=f"segmentation method (default {DEFAULT_METHOD})",
    )
    analyze.add_argument(
        "--sensitivity",
        type=_sensitivity,
        default=None,
        metavar="N",
        help="grey-level threshold 1..255, lower is more sensitive "
        "(default: automatic, from the measured camera noise)",
    )
    analyze.add_argument(
        "--min-area",
        type=_non_negative,
        default=100.0,
        metavar="PX",
        help="smallest object in pixels of the input frame (default 100)",
    )
    analyze.add_argument("--masks", action="store_true", help="also write masks/NNNNNN.png")
    analyze.add_argument(
        "--truth",
        type=_path,
        default=None,
        help="ground truth: a CDnet folder, a mask image or a box JSON file",
    )
    analyze.add_argument(
        "--calibration",
        type=_path,
        default=None,
        help="camera calibration JSON (docs/calibration.md): adds metres and km/h",
    )
    analyze.add_argument(
        "--fps",
        type=_fps,
        default=None,
        help="frame rate of a folder of frames (default 25), or instead of a video's own",
    )
    analyze.add_argument("--denoise", choices=DENOISE_METHODS, default="gaussian")
    analyze.add_argument("--denoise-kernel", type=int, choices=(1, 3, 5, 7), default=3)
    analyze.add_argument(
        "--enhance",
        choices=ENHANCE_METHODS,
        default="none",
        help="contrast enhancement before segmentation (default none)",
    )
    analyze.add_argument(
        "--detect-width",
        type=_detect_width,
        default=320,
        metavar="PX",
        help=f"detect on frames at most this wide, 0 = full size, else {MIN_DETECT_WIDTH} to "
        f"{MAX_DETECT_WIDTH} (default 320)",
    )
    analyze.add_argument(
        "--no-background-scan",
        dest="background_scan",
        action="store_false",
        help="learn the scene from the first frame, as a live camera does, instead of "
        "estimating it first from frames sampled over the first 30 s",
    )
    analyze.add_argument("--quiet", action="store_true", help="no progress bar and no summary")

    evaluate = commands.add_parser("evaluate", help="score an analyze output folder against truth")
    evaluate.add_argument("out", type=_path, help="the folder `vigil analyze` wrote")
    evaluate.add_argument(
        "--truth", type=_path, required=True, help="a CDnet folder, a mask image or a box JSON file"
    )
    commands.add_parser(
        "hash-password",
        help="print a VIGIL_PASSWORD_HASH (the password is read from stdin, or asked twice)",
    )
    return parser


def _quiet_opencv() -> None:
    """OpenCV's and FFmpeg's messages would break the one-line error contract on stderr,
    and a damaged file or a flaky camera repeats them for every frame; Vigil says what
    went wrong itself. ``OPENCV_FFMPEG_LOGLEVEL`` set by the user wins (24 = warnings,
    which OpenCV then prints on stdout)."""
    from app.sources.files import FFMPEG_LOG_QUIET

    # Read each time OpenCV opens a video, here and in every process started from here.
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", FFMPEG_LOG_QUIET)
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _quiet_opencv()
    if args.command == "serve":
        return _serve(args)
    if args.command == "hash-password":
        return _hash_password()
    if args.command == "analyze":
        return _analyze(args)
    return _evaluate(args)


def _fail(command: str, reason: object) -> int:
    print(f"vigil {command}: error: {reason}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _analyze(args: argparse.Namespace) -> int:
    from app.analysis.calibration_file import load_calibration
    from app.analysis.runner import AnalysisOptions, analyze
    from app.sources.files import open_input
    from app.vision.pipeline import PipelineConfig

    out = args.out or Path("vigil-out") / (args.input.stem or "input")
    if out.exists() and not out.is_dir():
        return _fail("analyze", f"the output folder is a file: {out}")
    try:
        calibration = None
        if args.calibration is not None:
            calibration = load_calibration(args.calibration, open_input(args.input, args.fps).size)
        options = AnalysisOptions(
            pipeline=PipelineConfig(
                method=args.method,
                sensitivity=args.sensitivity,
                min_area=args.min_area,
                denoise=args.denoise,
                denoise_kernel=args.denoise_kernel,
                enhance=args.enhance,
                detect_width=args.detect_width,
            ),
            masks=args.masks,
            truth=args.truth,
            calibration=calibration,
            fps=args.fps,
            background_scan=args.background_scan,
        )
        with _ProgressBar(enabled=not args.quiet and sys.stderr.isatty()) as bar:
            report = analyze(args.input, out, options, progress=bar.update)
    except ValueError as exc:  # InputError, TruthError, CalibrationError: the reason is the message
        return _fail("analyze", exc)
    except OSError as exc:
        return _fail("analyze", f"{exc.strerror or exc}: {exc.filename or out}")
    if not args.quiet:
        print(_summary(report, out))
    # Warnings are not progress or a summary: --quiet keeps them (a script wants to know).
    for warning in report.get("warnings", []):
        _warn("analyze", warning)
    _warn_if_nothing_scored("analyze", report.get("evaluation"))
    return 0


def _summary(report: dict[str, Any], out: Path) -> str:
    line = (
        f"{report['frames']} frames, {len(report['tracks'])} tracks, {report['events']} events "
        f"at {report['timings']['frames_per_s']} frames/s -> {out}"
    )
    evaluation = report.get("evaluation")
    if evaluation:
        objects = evaluation["objects"]
        line += f"\nDR {_rate(objects['detection_rate'])}  FAR {_rate(objects['false_alarm_rate'])}"
        if "pixels" in evaluation:
            line += f"  pixel F-measure {evaluation['pixels']['f_measure']:.3f}"
    return line


def _rate(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3f}"


class _ProgressBar:
    """A tqdm bar on a terminal; nothing in scripts or with --quiet."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self._bar: Any = None

    def __enter__(self) -> _ProgressBar:
        if self.enabled:
            from tqdm import tqdm

            self._bar = tqdm(unit="frame", dynamic_ncols=True)
        return self

    def update(self, done: int, expected: int | None) -> None:
        if self._bar is None:
            return
        if expected and expected >= done:
            self._bar.total = expected
        self._bar.update(done - self._bar.n)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.close()


def _evaluate(args: argparse.Namespace) -> int:
    from app.analysis.evaluate import evaluate

    try:
        result = evaluate(args.out, args.truth)
    except ValueError as exc:
        return _fail("evaluate", exc)
    print(json.dumps(result, indent=2))
    _warn_if_nothing_scored("evaluate", result)
    return 0


def _warn(command: str, message: str) -> None:
    print(f"vigil {command}: warning: {message}", file=sys.stderr)


def _warn_if_nothing_scored(command: str, evaluation: dict[str, Any] | None) -> None:
    if evaluation is not None and not evaluation["frames_scored"]:
        _warn(
            command,
            "no frame of the input has ground truth "
            "(check the truth's frame numbers); nothing was scored",
        )


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _serve(args: argparse.Namespace) -> int:
    from pydantic import ValidationError

    from app.core.config import Settings

    overrides: dict[str, Any] = {}
    if args.host is not None:
        overrides["host"] = args.host
    if args.port is not None:
        overrides["port"] = args.port
    if args.data is not None:
        overrides["data_dir"] = args.data
    try:
        settings = Settings(**overrides)
    except ValidationError as exc:  # A bad VIGIL_* variable.
        error = exc.errors()[0]
        return _fail("serve", f"VIGIL_{str(error['loc'][0]).upper()}: {error['msg']}")
    # Settings reads VIGIL_PASSWORD and VIGIL_PASSWORD_HASH.
    if not _is_loopback(settings.host) and not (settings.password or settings.password_hash):
        return _fail(
            "serve",
            f"refusing to listen on {settings.host} without a password: "
            "set VIGIL_PASSWORD or VIGIL_PASSWORD_HASH (or bind to 127.0.0.1)",
        )
    try:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        if not os.access(settings.data_dir, os.W_OK | os.X_OK):
            raise PermissionError(errno.EACCES, "not writable", str(settings.data_dir))
    except OSError as exc:
        return _fail("serve", f"cannot use data folder {settings.data_dir}: {exc.strerror}")
    failed = _migrate(settings.database)
    if failed:
        return _fail("serve", failed)
    import uvicorn

    from app.api.app import SERVER_OPTIONS, create_app

    try:
        application = create_app(settings)
    except ValueError as exc:  # A bad VIGIL_PASSWORD_HASH: the message does not repeat it.
        return _fail("serve", exc)
    uvicorn.run(
        application,
        host=settings.host,
        port=settings.port,
        timeout_graceful_shutdown=3,
        log_level="info",
        **SERVER_OPTIONS,
    )
    return 0


def _migrate(target: Path | str) -> str | None:
    """Bring the database's schema up to this release's before the server starts (it finds
    nothing left to do); why that failed, in one line without a password, or None."""
    from sqlalchemy.exc import DBAPIError

    from app.storage.engine import shown
    from app.storage.migrate import SchemaError, upgrade

    try:
        upgrade(target)
    except SchemaError as exc:
        return str(exc)
    except DBAPIError as exc:  # Unreachable, refused, not a database...
        reason = str(exc.orig).strip().splitlines()[0] if exc.orig else type(exc).__name__
        return f"cannot use the database {shown(target)}: {reason}"
    return None


def _hash_password() -> int:
    import getpass

    from app.api.security import PasswordHash

    if sys.stdin.isatty():
        password = getpass.getpass("Password: ")
        if getpass.getpass("Again: ") != password:
            return _fail("hash-password", "the two passwords differ")
    else:
        password = sys.stdin.readline().rstrip("\r\n")
    if not password:
        return _fail("hash-password", "empty password")
    print(PasswordHash.create(password).encode())
    return 0
