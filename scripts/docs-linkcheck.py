#!/usr/bin/env python3
"""Check the built book (docs/book) and README.md for broken relative links.

mdbook 0.4 has no link check of its own. This reads every HTML page mdbook wrote and
checks each relative href/src: the file must exist under docs/book, and a #fragment must be
an id on the page it points to. It also checks the Markdown sources: a link in docs/src
must not leave docs/src (mdbook would not copy the target), and every relative link in
README.md must name a file of the repository (and, for docs/src/*.md#anchor, a heading).
Exit status 1 on any broken link, with a list.

With --sources it reads the Markdown only, no book needed (what `make lint` runs, in well
under a second): the checks above on docs/src and README.md, plus each chapter-to-chapter
link's file must be a chapter of SUMMARY.md (mdbook renders no other) and its #anchor a
heading of that chapter. The built-book check stays the final word: it also sees the ids
mdbook makes unique and the links inside included files.

    scripts/docs-linkcheck.py [BOOK_DIR]     # default docs/book
    scripts/docs-linkcheck.py --sources      # docs/src and README.md, without building
"""

import html.parser
import re
import sys
import urllib.parse
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "docs" / "src"


class Page(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.links = set(), []

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            if k in ("id", "name") and v:
                self.ids.add(v)
            if k in ("href", "src") and v:
                self.links.append(v)


def parse(path, cache={}):
    if path not in cache:
        p = Page()
        p.feed(path.read_text(errors="replace"))
        cache[path] = p
    return cache[path]


def external(u):
    return re.match(r"^[a-z][a-z0-9+.-]*:", u, re.I) is not None or u.startswith("//")


def check_book(book):
    bad = []
    pages = sorted(book.rglob("*.html"))
    if not pages:
        return [f"{book}: no HTML pages (was the book built?)"]
    for page in pages:
        if page.name in ("print.html", "toc.html", "404.html"):
            continue  # print.html repeats every page; toc.html is mdbook's own navigation
        for u in parse(page).links:
            if external(u) or u.startswith("javascript:"):
                continue
            path, _, frag = u.partition("#")
            path = urllib.parse.unquote(path.split("?")[0])
            target = page if not path else (page.parent / path).resolve()
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                bad.append(f"{page.relative_to(book)}: {u}: no such file")
                continue
            if frag and target.suffix == ".html" and urllib.parse.unquote(frag) not in parse(target).ids:
                bad.append(f"{page.relative_to(book)}: {u}: no id '{frag}' in {target.name}")
    return bad


def slug(heading):
    # mdbook 0.4's id: lower case, keep alphanumerics, '-' and '_', spaces to '-'.
    text = re.sub(r"<[^>]+>", "", heading).strip().lower()
    text = text.replace("`", "")
    return "".join(c if (c.isalnum() or c in "-_") else "-" if c == " " else "" for c in text)


def md_anchors(path):
    ids, fence = set(), False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            fence = not fence
        m = re.match(r"^#{1,6} (.*)", line)
        if m and not fence:
            ids.add(slug(m.group(1)))
    return ids


LINK = re.compile(r"\]\(([^)\s]+)\)")


def md_links(path):
    fence = False
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if line.startswith("```"):
            fence = not fence
            continue
        if fence:
            continue
        for m in LINK.finditer(re.sub(r"`[^`]*`", "", line)):
            yield n, m.group(1)


def chapters():
    """The chapters SUMMARY.md lists, resolved."""
    summary = SRC / "SUMMARY.md"
    return {(SRC / u.partition("#")[0]).resolve() for _, u in md_links(summary) if not external(u)}


def check_markdown(sources_only=False):
    bad = []
    listed = chapters() if sources_only else set()
    for md in sorted(SRC.rglob("*.md")):
        for n, u in md_links(md):
            if external(u):
                continue
            path, _, frag = u.partition("#")
            if not path and not sources_only:
                continue  # the built page's ids are checked in check_book
            target = (md.parent / path).resolve() if path else md.resolve()
            if SRC.resolve() not in target.parents:
                bad.append(f"{md.relative_to(ROOT)}:{n}: {u}: leaves docs/src (the book would not have it)")
            elif not target.exists():
                bad.append(f"{md.relative_to(ROOT)}:{n}: {u}: no such file")
            elif sources_only and target.suffix == ".md" and md.name != "SUMMARY.md":
                if target not in listed:
                    bad.append(f"{md.relative_to(ROOT)}:{n}: {u}: not a chapter of SUMMARY.md (mdbook would not render it)")
                elif frag and frag not in md_anchors(target):
                    bad.append(f"{md.relative_to(ROOT)}:{n}: {u}: no heading '{frag}' in {target.name}")
        for n, line in enumerate(md.read_text().splitlines(), 1):
            for inc in re.findall(r"\{\{#include ([^}:\s]+)", line):
                if not (md.parent / inc).exists():
                    bad.append(f"{md.relative_to(ROOT)}:{n}: {{{{#include {inc}}}}}: no such file")
    readme = ROOT / "README.md"
    for n, u in md_links(readme):
        if external(u):
            continue
        path, _, frag = u.partition("#")
        target = (ROOT / path) if path else readme
        if not target.exists():
            bad.append(f"README.md:{n}: {u}: no such file")
        elif frag and target.suffix == ".md" and frag not in md_anchors(target):
            bad.append(f"README.md:{n}: {u}: no heading '{frag}' in {path or 'README.md'}")
    return bad


def main():
    if sys.argv[1:] == ["--sources"]:
        bad = check_markdown(sources_only=True)
        for b in bad:
            print(f"broken link: {b}", file=sys.stderr)
        print(f"docs-linkcheck --sources: {len(bad)} broken link(s) in docs/src and README.md", file=sys.stderr)
        return 1 if bad else 0
    book = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "book"
    bad = check_markdown() + check_book(book)
    for b in bad:
        print(f"broken link: {b}", file=sys.stderr)
    n = sum(len(parse(p).links) for p in book.rglob("*.html")) if book.exists() else 0
    print(f"docs-linkcheck: {len(bad)} broken link(s); {n} links in {book.relative_to(ROOT) if book.is_relative_to(ROOT) else book} checked, and README.md", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
