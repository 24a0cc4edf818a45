"""The README and the book's pages as the docs checks read them (shared by check_docs.py and
check_book_links.py)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BOOK = ROOT / "docs" / "src"
INCLUDE = re.compile(r"\{\{#include ([^}\s]+)\}\}")
# A fenced block: its language (group 1) and body (group 2).
FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```[ \t]*$", re.S | re.M)


def read_page(page: Path) -> str:
    """The page's text with mdBook's `{{#include FILE}}` directives expanded."""
    return INCLUDE.sub(lambda m: (page.parent / m.group(1)).read_text(), page.read_text())


def book_pages() -> list[Path]:
    """The book's pages in SUMMARY.md order."""
    summary = (BOOK / "SUMMARY.md").read_text()
    return [BOOK / link for link in re.findall(r"\]\(([^)#]+\.md)\)", summary)]
