"""The Chromium page of the API tests, for a page on a node of a site."""

from tests.api.conftest import page

__all__ = ["page"]
