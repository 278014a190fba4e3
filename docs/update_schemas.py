"""Write the /ws messages' JSON Schemas into docs/websocket.md, from their models.

    python docs/update_schemas.py

Each schema block follows a ``<!-- schema: ModelName -->`` line; each example a
``<!-- example -->`` line. tests/events/test_messages.py checks that the blocks are what the
models give and that each example parses as a message.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from app.events.messages import message_schemas

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "websocket.md"
SCHEMA = re.compile(r"(<!-- schema: (\w+) -->\n```json\n)(.*?)(\n```)", re.DOTALL)
EXAMPLE = re.compile(r"<!-- example -->\n```json\n(.*?)\n```", re.DOTALL)


def blocks(text: str) -> dict[str, str]:
    """The schema blocks of ``text``, by model name."""
    return {match[2]: match[3] for match in SCHEMA.finditer(text)}


def examples(text: str) -> list[str]:
    """The example messages of ``text``."""
    return [match[1] for match in EXAMPLE.finditer(text)]


def updated(text: str) -> str:
    """``text`` with each schema block as its model gives it now."""
    schemas = message_schemas()

    def block(match: re.Match[str]) -> str:
        schema = json.dumps(schemas[match[2]], indent=2, ensure_ascii=False)
        return match[1] + schema + match[4]

    return SCHEMA.sub(block, text)


if __name__ == "__main__":
    DOC.write_text(updated(DOC.read_text()))
