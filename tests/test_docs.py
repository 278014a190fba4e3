"""The README stays short and the docs stay true: every link resolves, and
docs/configuration.md lists every ``VIGIL_*`` setting as app/core/config.py has it."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
from annotated_types import Ge, Gt, Le

from app.core.config import Settings

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
README_MOST_WORDS = 1000
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
HEADING = re.compile(r"^#+ (.+)$", re.MULTILINE)
SETTING_ROW = re.compile(r"^\| `VIGIL_(\w+)` \| `([^`]*)` \|([^|]*)\|", re.MULTILINE)


def test_the_readme_reads_in_five_minutes() -> None:
    """Words as ``wc -w`` counts them, code included."""
    text = (ROOT / "README.md").read_text()
    assert len(text.split()) < README_MOST_WORDS
    assert "make run" in text and "make test" in text


def _anchor(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, no punctuation, spaces as hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(page: Path) -> None:
    text = page.read_text()
    broken = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target):  # https:, mailto:: not checked here.
            continue
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.exists():
            broken.append(target)
        elif anchor and file.suffix == ".md":
            anchors = {_anchor(h) for h in HEADING.findall(file.read_text())}
            if anchor not in anchors:
                broken.append(target)
    assert not broken, f"{page.name}: links to nothing: {broken}"


def _shown(value: Any) -> str:
    """A default as docs/configuration.md writes it."""
    if value is None or value == "":
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
