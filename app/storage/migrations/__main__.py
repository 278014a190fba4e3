"""``python -m app.storage.migrations revision -m "what"``: a new, empty migration in
``versions/``, numbered after the last, from ``script.py.mako`` (for developers)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from alembic import command

from app.storage.migrate import config, head


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m app.storage.migrations")
    commands = parser.add_subparsers(dest="command", required=True)
    new = commands.add_parser("revision", help="write a new, empty migration")
    new.add_argument("-m", "--message", required=True, help="what it changes")
    args = parser.parse_args(argv)
    number = f"{int(head()) + 1:04d}"
    command.revision(config(), message=args.message, rev_id=number, head=head())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
