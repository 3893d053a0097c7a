#!/usr/bin/env python3
"""Lists C++ function definitions longer than a limit (lines from the signature to the closing brace).

A brace counter, not a parser: comments, string and character literals are blanked, then every `{` at
namespace or class scope is classified by the text before it (namespace/class/struct/enum/union scope,
an initializer, a brace-initialised member in a constructor's initializer list, or a function body).
Lambdas and blocks inside a function count as part of it.

  check_function_length.py [--max N] [--allow FILE:NAME]... PATH...
      exit 1 when a function is longer than N lines (default 80); --allow names a known exception
      (path suffix and function name), reported but not failing
  check_function_length.py --self-test         the counter on synthetic sources (a 81-line function fails)
"""
import argparse
import pathlib
import re
import sys

SCOPE_RE = re.compile(r'^(template\s*<.*>\s*)?(inline\s+)?(namespace|class|struct|union|enum)\b|^extern\s*"C"', re.S)
INIT_LIST_RE = re.compile(r'\)\s*(noexcept\s*)?:(?!:)', re.S)


def blank(text):
    """Comments and literals replaced by spaces (newlines kept, so line numbers stay)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith('//', i):
            j = text.find('\n', i)
            j = n if j < 0 else j
            out.append(' ' * (j - i)); i = j
        elif text.startswith('/*', i):
            j = text.find('*/', i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r'[^\n]', ' ', text[i:j])); i = j
        elif c == 'R' and text.startswith('R"', i):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            end = text.find(')' + m.group(1) + '"', i) if m else -1
            j = n if end < 0 else end + len(m.group(1)) + 2
            out.append('""' + re.sub(r'[^\n]', ' ', text[i + 2:j])); i = j
        elif c in '"\'':
            if c == "'" and i > 0 and (text[i - 1].isalnum()) :  # digit separator 1'000
                out.append(c); i += 1; continue
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == '\\' else 1
            out.append(c + ' ' * (min(j, n) - i - 1) + c); i = j + 1
        elif c == '#' and (i == 0 or text[i - 1] == '\n'):  # preprocessor line (with continuations)
            j = i
            while True:
                k = text.find('\n', j)
                if k < 0: k = n; break
                if text[k - 1] != '\\': break
                j = k + 1
            out.append(re.sub(r'[^\n]', ' ', text[i:k])); i = k
        else:
            out.append(c); i += 1
    return ''.join(out)


def matching_brace(text, i):
    depth = 0
    for j in range(i, len(text)):
        if text[j] == '{': depth += 1
        elif text[j] == '}':
            depth -= 1
            if depth == 0: return j
    return len(text) - 1


def function_name(header):
    init_list = INIT_LIST_RE.search(header)
    if init_list:
        header = header[:init_list.start() + 1]
    m = re.search(r'([~\w:]+(operator\s*\S+?)?)\s*\((?:[^()]|\([^()]*\))*\)[^()]*$', header, re.S)
    return m.group(1) if m else header.strip().split('\n')[-1][:60]


def functions(text):
    """(name, first line, last line) of every function body at namespace or class scope."""
    found = []

    def scan(start, end):
        header_start, i = start, start
        while i < end:
            c = text[i]
            if c in ';}':
                header_start = i + 1
            elif c == '{':
                header = text[header_start:i].strip()
                close = matching_brace(text, i)
                if SCOPE_RE.match(header) and '(' not in header.split('{')[0].split(':')[0]:
                    scan(i + 1, close)
                    header_start = close + 1
                elif header.endswith('=') or '(' not in header or header.endswith(','):
                    pass  # an initializer: the declaration goes on after it
                elif INIT_LIST_RE.search(header) and header[-1] not in ')}':
                    pass  # a brace-initialised member in a constructor's initializer list
                else:
                    lead = len(text[header_start:i]) - len(text[header_start:i].lstrip())
                    first = text.count('\n', 0, header_start + lead) + 1
                    last = text.count('\n', 0, close) + 1
                    found.append((function_name(header), first, last))
                    header_start = close + 1
                i = close
            i += 1

    scan(0, len(text))
    return found


def long_functions(path, limit):
    text = blank(pathlib.Path(path).read_text(encoding='utf-8', errors='replace'))
    return [(name, first, last - first + 1) for name, first, last in functions(text) if last - first + 1 > limit]


def self_test():
    body = '\n'.join('  x += %d;' % k for k in range(79))
    source = ('namespace a {\nstruct S {\n  int m{1};\n  S() : m{2} {}\n  int f() const {\n' + body + '\n  }\n};\n'
              'int g(int x) {  // "{" in a comment\n  const char *s = "}";\n  return x;\n}\n}  // namespace a\n')
    found = {name: (first, last) for name, first, last in functions(blank(source))}
    expect = {'S': (4, 4), 'f': (5, 85), 'g': (87, 90)}
    ok = found == expect
    print('functions found:', found, '' if ok else '(expected %s)' % expect)
    long = [n for n, f, l in functions(blank(source)) if l - f + 1 > 80]
    ok = ok and long == ['f']  # negative control: an 81-line function is caught
    print('over 80 lines:', long)
    return 0 if ok else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('paths', nargs='*')
    ap.add_argument('--max', type=int, default=80)
    ap.add_argument('--allow', action='append', default=[], metavar='FILE:NAME')
    ap.add_argument('--self-test', action='store_true')
    a = ap.parse_args()
    if a.self_test:
        return self_test()
    files = []
    for p in map(pathlib.Path, a.paths):
        files += sorted(q for q in p.rglob('*') if q.suffix in ('.cpp', '.h')) if p.is_dir() else [p]
    def allowed(f, name):
        return any(str(f).endswith(e.split(':', 1)[0]) and name == e.split(':', 1)[1] for e in a.allow)

    bad, excused = [], []
    for f in files:
        for name, first, n in long_functions(f, a.max):
            (excused if allowed(f, name) else bad).append((f, name, first, n))
    for f, name, first, n in excused:
        print('%s:%d: %s is %d lines (limit %d; allowed exception)' % (f, first, name, n, a.max))
    for f, name, first, n in bad:
        print('%s:%d: %s is %d lines (limit %d)' % (f, first, name, n, a.max))
    print('%d file(s), %d function(s) over %d lines (%d allowed)' % (len(files), len(bad), a.max, len(excused)))
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
