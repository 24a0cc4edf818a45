#!/usr/bin/env python3
"""Every internal link of the README and the book resolves, offline: the file exists, and an
anchor (`page.md#a-heading`) names a heading of that page as mdBook numbers it. A book page
links only inside the book (`docs/src/`) or to files images the book carries: anything else
would be a broken link in the built HTML. Also: every page the book holds is in SUMMARY.md.

    python3 scripts/check_book_links.py
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from book_pages import BOOK, FENCE, ROOT, book_pages, read_page

LINK = re.compile(r"(?<!!)\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")


def mdbook_id(heading: str) -> str:
    """The id mdBook gives a heading (its `normalize_id` on the heading's text)."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link's text
    text = re.sub(r"[`*_]{1,2}(?=\S)|(?<=\S)[`*_]{1,2}", "", text)
    return "".join(
        c.lower() if c.isalnum() or c in "_-" else "-" if c.isspace() else ""
        for c in text
    )


def anchors(page: Path) -> set[str]:
    seen: dict[str, int] = {}
    out = set()
    for line in FENCE.sub("", read_page(page)).splitlines():
        m = HEADING.match(line)
        if m:
            base = mdbook_id(m.group(2))
            n = seen.get(base, 0)
            out.add(base if n == 0 else f"{base}-{n}")
            seen[base] = n + 1
    return out


def check(page: Path, in_book: bool) -> list[str]:
    errors = []
    text = FENCE.sub(lambda m: "\n" * m.group().count("\n"), read_page(page))
    for m in LINK.finditer(text):
        target = m.group(1) or m.group(2)
        line = text[: m.start()].count("\n") + 1
        where = f"{page.relative_to(ROOT)}:{line}: {target}"
        if re.match(r"[a-z]+:", target):
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            errors.append(f"{where}: no such file")
            continue
        if in_book and BOOK not in dest.parents and dest != BOOK:
            errors.append(f"{where}: outside the book (docs/src), broken in the built HTML")
            continue
        if anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            errors.append(f"{where}: no heading with id #{anchor} in {dest.relative_to(ROOT)}")
    return errors


def main() -> None:
    listed = {p.resolve() for p in book_pages()}
    errors = check(ROOT / "README.md", in_book=False)
    pages = sorted(BOOK.rglob("*.md"))
    for page in pages:
        errors += check(page, in_book=True)
        if page.name != "SUMMARY.md" and page.resolve() not in listed:
            errors.append(f"{page.relative_to(ROOT)}: not in SUMMARY.md (mdBook would not build it)")
    if errors:
        print("\n".join(errors))
        sys.exit(f"{len(errors)} broken links")
    print(f"README.md and {len(pages)} book pages: every internal link and anchor resolves")


if __name__ == "__main__":
    main()
