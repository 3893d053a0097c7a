#!/usr/bin/env python3
"""Checks that every relative link and image in README.md and docs/**/*.md points to a file that exists.

    python3 tools/check_doc_links.py            # the repository this script is in; exit 1 on a broken link
    python3 tools/check_doc_links.py --root DIR # another tree (README.md and docs/ under DIR)

Checked: inline links and images `[text](target)` / `![alt](target)` (the text may span lines), reference
definitions `[id]: target`, and HTML `src="..."` / `href="..."`. Ignored: targets with a scheme (http:, https:,
mailto:, ...), pure `#anchor`s, and anything inside fenced code blocks or inline code spans. For `file#anchor` only
the file is checked. A target is resolved against the linking file's folder (a leading `/`: against the root).
Before the check the script runs its own parser on a built-in sample (one good and one broken link) and stops if
that does not find exactly the broken one, and it fails if it finds no link at all in the tree.
"""
import argparse
import os
import re
import sys
import tempfile
import urllib.parse

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1")
INLINE = re.compile(r"\]\(\s*(<[^>\n]*>|[^)\s]+)(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^)]*\)))?\s*\)")
REF_DEF = re.compile(r"^ {0,3}\[[^\]\n]+\]:\s*(<[^>\n]*>|\S+)")
HTML = re.compile(r"\b(?:src|href)\s*=\s*\"([^\"]+)\"")
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def strip_code(text):
    """The text with fenced blocks and inline code spans blanked (newlines kept, so offsets map to lines)."""
    out, fence = [], None
    for line in text.split("\n"):
        m = FENCE.match(line)
        if fence is None and m:
            fence = m.group(1)[0] * len(m.group(1))
            out.append("")
        elif fence is not None:
            if m and m.group(1).startswith(fence):
                fence = None
            out.append("")
        else:
            out.append(CODE_SPAN.sub(lambda s: " " * len(s.group(0)), line))
    return "\n".join(out)


def targets(text):
    """(line number, target) of every link-like target in a markdown text."""
    body = strip_code(text)
    found = []
    for regex in (INLINE, HTML):
        for m in regex.finditer(body):
            found.append((body.count("\n", 0, m.start(1)) + 1, m.group(1).strip("<>")))
    lines, in_defs = body.split("\n"), True  # a definition starts a paragraph or follows one ("[0, 90]: D" does not)
    for number, line in enumerate(lines, 1):
        m = REF_DEF.match(line)
        if m and in_defs:
            found.append((number, m.group(1).strip("<>")))
        in_defs = not line.strip() or bool(m and in_defs)
    return sorted(found)


def broken_links(root, md_path):
    """[(line, target)] of the local targets in md_path that name no existing file or folder, and the count checked."""
    with open(md_path, encoding="utf-8") as f:
        text = f.read()
    bad, checked = [], 0
    for line, target in targets(text):
        if not target or target.startswith("#") or SCHEME.match(target):
            continue
        path = urllib.parse.unquote(target.split("#", 1)[0].split("?", 1)[0])
        if not path:
            continue
        base = root if path.startswith("/") else os.path.dirname(md_path)
        checked += 1
        if not os.path.exists(os.path.normpath(os.path.join(base, path.lstrip("/")))):
            bad.append((line, target))
    return bad, checked


def markdown_files(root):
    files = [os.path.join(root, "README.md")] if os.path.isfile(os.path.join(root, "README.md")) else []
    for folder, dirs, names in os.walk(os.path.join(root, "docs")):
        dirs.sort()
        files += [os.path.join(folder, n) for n in sorted(names) if n.endswith(".md")]
    return files


def self_test():
    """The parser on a sample: a good link, a good image over two lines, ignored kinds, and one broken link."""
    with tempfile.TemporaryDirectory() as tmp:
        os.makedirs(os.path.join(tmp, "docs", "sub"))
        open(os.path.join(tmp, "docs", "a.png"), "w").close()
        sample = ("# t\n[ok](a.png#x) ![two\nlines](a.png \"title\") [web](https://example.com/x) [anchor](#y)\n"
                  "`[code](missing1.md)`\n```\n[fenced](missing2.md)\n```\n\n[ref]: sub/../a.png\n"
                  "text [gone](sub/missing3.md) end\nnot a\n[0, 9]: definition\n")
        with open(os.path.join(tmp, "docs", "s.md"), "w") as f:
            f.write(sample)
        bad, checked = broken_links(tmp, os.path.join(tmp, "docs", "s.md"))
    if bad != [(10, "sub/missing3.md")] or checked != 4:
        sys.exit("check_doc_links.py: self-test failed: broken %r, checked %d (expected [(10, 'sub/missing3.md')], 4)"
                 % (bad, checked))


def main():
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=repo, help="the tree to check (default: this repository)")
    args = ap.parse_args()
    self_test()
    files = markdown_files(args.root)
    total, failures = 0, []
    for md in files:
        bad, checked = broken_links(args.root, md)
        total += checked
        failures += [(os.path.relpath(md, args.root), line, target) for line, target in bad]
    for md, line, target in failures:
        print("%s:%d: no such file: %s" % (md, line, target))
    print("%d markdown files, %d local links checked, %d broken" % (len(files), total, len(failures)))
    if total == 0:
        sys.exit("check_doc_links.py: no local link found under %s (wrong --root?)" % args.root)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
