"""Where the page's files are: inside the package when Vigil is installed from a wheel or
an image (``app/static``, ``app/templates``), at the top of the repository in a checkout
(``static/``, ``templates/``), editable installs included."""

from __future__ import annotations

from pathlib import Path

import app as vigil_package

PACKAGE_DIR = Path(vigil_package.__file__).resolve().parent


def _page_dir(name: str) -> Path:
    packaged = PACKAGE_DIR / name
    return packaged if packaged.is_dir() else PACKAGE_DIR.parent / name


STATIC_DIR = _page_dir("static")
TEMPLATES_DIR = _page_dir("templates")
