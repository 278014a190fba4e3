"""The docs stay true: docs/configuration.md lists every ``VIGIL_*`` setting as
app/core/config.py has it."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from annotated_types import Ge, Gt, Le

from app.core.config import Settings

ROOT = Path(__file__).resolve().parents[1]
SETTING_ROW = re.compile(r"^\| `VIGIL_(\w+)` \| `([^`]*)` \|([^|]*)\|", re.MULTILINE)


def _shown(value: Any) -> str:
    """A default as docs/configuration.md writes it."""
    if value is None:
        return "unset"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


def _allowed(metadata: list[Any]) -> str:
    """A setting's bounds as docs/configuration.md writes them."""
    low = next((f">= {m.ge}" for m in metadata if isinstance(m, Ge)), None)
    low = low or next((f"> {m.gt}" for m in metadata if isinstance(m, Gt)), None)
    high = next((m.le for m in metadata if isinstance(m, Le)), None)
    if low and high is not None:
        return f"{low.removeprefix('>= ')} to {high}"
    return low or ("" if high is None else f"<= {high}")


def test_the_configuration_page_lists_every_setting_with_its_default_and_bounds() -> None:
    """A setting added, removed, or given another default or bounds in app/core/config.py
    fails here until docs/configuration.md says so."""
    documented = {
        name.lower(): (default, allowed.strip())
        for name, default, allowed in SETTING_ROW.findall(
            (ROOT / "docs" / "configuration.md").read_text()
        )
    }
    actual = {
        name: (_shown(field.default), _allowed(field.metadata))
        for name, field in Settings.model_fields.items()
    }
    assert documented == actual
