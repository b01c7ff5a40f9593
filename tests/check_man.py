#!/usr/bin/python3
"""tests/check_man.py - keeps the man pages in man/ true to the programs they describe.

    tests/check_man.py MANDIR BUILDDIR             lint, content checks and the self-test
                                                   (make check-man)
    tests/check_man.py --no-lint MANDIR BUILDDIR   content checks only
    tests/check_man.py --self-test BUILDDIR        the content checks must fail on copies of
                                                   the pages with one flag, command, option or
                                                   function taken out (or a flag added that
                                                   does not exist)

Lint: `mandoc -Tlint -Wwarning` on every page; any warning fails.
Content, from the built programs and the public header, so that a flag added to the code
without its page (or documented without existing) fails here:
  seamtexd.8       every long flag `seamtexd --help` prints appears in the page; every flag the
                   page lists as an item (.It Fl \\-x) is in --help
  seamtex.1        every command of `seamtex --help` has its item (.It Cm x); every long option
                   of `seamtex --help` and of each `seamtex COMMAND --help` appears; every
                   flag the page lists as an item is in one of those helps
  seamtex-bench.1  every long option of `seamtex-bench --help` appears, every item's in it
  seamtex-render.1 every long option of `seamtex-render --help` appears, every item's in it
  libseamtex.3     every stc_ function declared in client/seamtex.h, client/seamtex_cluster.h or
                   client/seamtex_etcd.h
                   has its .Fn line, and every .Fn stc_x line of the page names a declared
                   function
  seamtex-python.3 every public name of python/seamtex/__init__.pyi appears: module
                   constants, classes (the exceptions too), methods, attributes, properties
"Appears" is checked on the page as mandoc renders it, as a whole word. Python's standard
library only; one process per program run (process start-up is slow on a loaded machine).
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LONG = re.compile(r"--[a-z][a-z0-9-]*")
HEADERS = ("seamtex.h", "seamtex_cluster.h", "seamtex_etcd.h")   # what libseamtex.3 documents


def run(argv):
    return subprocess.run(argv, check=True, capture_output=True, text=True).stdout


def render(path):
    out = subprocess.run(["mandoc", "-Tascii", "-O", "width=400", path], check=True,
                         capture_output=True).stdout
    return re.sub(rb".\x08", b"", out).decode("utf-8", "replace")


def has_word(text, word):
    return re.search(r"(^|[^A-Za-z0-9_-])" + re.escape(word) + r"([^A-Za-z0-9_-]|$)", text,
                     re.M) is not None


def gather(build):
    """The help texts of the programs and the header's functions, read once."""
    h = {"seamtexd": run([os.path.join(build, "seamtexd"), "--help"]),
         "seamtex": run([os.path.join(build, "seamtex"), "--help"]),
         "bench": run([os.path.join(build, "seamtex-bench"), "--help"]),
         "render": run([os.path.join(build, "seamtex-render"), "--help"]), "cmd": {}}
    for c in sorted(set(re.findall(r"^  ([a-z]+)(?: |$)", h["seamtex"], re.M))):
        h["cmd"][c] = run([os.path.join(build, "seamtex"), c, "--help"])
    h["decl"] = set()
    for hdr in HEADERS:
        with open(os.path.join(ROOT, "client", hdr)) as f:
            h["decl"] |= set(re.findall(r"\b(stc_[a-z0-9_]+)\s*\(", f.read()))
    h["py"] = pyi_names(os.path.join(ROOT, "python", "seamtex", "__init__.pyi"))
    return h


def pyi_names(path):
    """The public names of the stubs: module-level names and classes, and the methods,
    attributes and properties of each class (dunders and _private names left out, except
    __version__)."""
    names = set()
    with open(path) as f:
        for line in f:
            m = (re.match(r"^class ([A-Za-z]\w*)", line) or re.match(r"^([A-Za-z]\w*|__version__)\s*:", line)
                 or re.match(r"^    def ([A-Za-z]\w*)", line) or re.match(r"^    ([A-Za-z]\w*)\s*:", line))
            if m:
                names.add(m.group(1))
    return names


def item_flags(src):
    """The long flags a page defines: those on its list items (.It Fl \\-x ...)."""
    items = re.findall(r"^\.It .*$", src, re.M)
    return sorted({"--" + m for it in items for m in re.findall(r"Fl \\-([a-z][a-z0-9-]*)", it)})


def content(man, h):
    errs = []
    src = {p: open(os.path.join(man, p)).read()
           for p in ("seamtexd.8", "seamtex.1", "seamtex-bench.1", "seamtex-render.1",
                     "libseamtex.3", "seamtex-python.3")}
    # seamtexd.8
    text = render(os.path.join(man, "seamtexd.8"))
    for f in sorted(set(LONG.findall(h["seamtexd"]))):
        if not has_word(text, f):
            errs.append(f"seamtexd.8 does not document {f} (seamtexd --help has it)")
    for f in item_flags(src["seamtexd.8"]):
        if not has_word(h["seamtexd"], f):
            errs.append(f"seamtexd.8 documents {f}, which seamtexd --help does not list")
    # seamtex.1
    text = render(os.path.join(man, "seamtex.1"))
    if not h["cmd"]:
        errs.append("no command found in seamtex --help")
    for c, chelp in h["cmd"].items():
        if not re.search(r"^\.It Cm " + re.escape(c) + r"( |$)", src["seamtex.1"], re.M):
            errs.append(f"seamtex.1 has no item for the command '{c}'")
        for f in sorted(set(LONG.findall(chelp))):
            if not has_word(text, f):
                errs.append(f"seamtex.1 does not document '{c} {f}'")
    for f in sorted(set(LONG.findall(h["seamtex"]))):
        if not has_word(text, f):
            errs.append(f"seamtex.1 does not document {f} (seamtex --help has it)")
    helps = h["seamtex"] + "\n".join(h["cmd"].values())
    for f in item_flags(src["seamtex.1"]):
        if not has_word(helps, f):
            errs.append(f"seamtex.1 documents {f}, which neither seamtex --help nor a "
                        "seamtex COMMAND --help lists")
    # seamtex-bench.1
    text = render(os.path.join(man, "seamtex-bench.1"))
    for f in sorted(set(LONG.findall(h["bench"]))):
        if not has_word(text, f):
            errs.append(f"seamtex-bench.1 does not document {f}")
    for f in item_flags(src["seamtex-bench.1"]):
        if not has_word(h["bench"], f):
            errs.append(f"seamtex-bench.1 documents {f}, which seamtex-bench --help does not list")
    # seamtex-render.1
    text = render(os.path.join(man, "seamtex-render.1"))
    for f in sorted(set(LONG.findall(h["render"]))):
        if not has_word(text, f):
            errs.append(f"seamtex-render.1 does not document {f}")
    for f in item_flags(src["seamtex-render.1"]):
        if not has_word(h["render"], f):
            errs.append(f"seamtex-render.1 documents {f}, which seamtex-render --help does not list")
    # libseamtex.3
    if not h["decl"]:
        errs.append("no stc_ function found in client/seamtex.h or client/seamtex_cluster.h")
    documented = set(re.findall(r"^\.Fn (stc_[a-z0-9_]+)(?: |$)", src["libseamtex.3"], re.M))
    for fn in sorted(h["decl"] - documented):
        errs.append(f"libseamtex.3 does not document {fn}")
    for fn in sorted(documented - h["decl"]):
        errs.append(f"libseamtex.3 documents {fn}, which no public header declares")
    # seamtex-python.3
    text = render(os.path.join(man, "seamtex-python.3"))
    if not h["py"]:
        errs.append("no public name found in python/seamtex/__init__.pyi")
    for name in sorted(h["py"]):
        if not has_word(text, name):
            errs.append(f"seamtex-python.3 does not document {name} (python/seamtex/__init__.pyi has it)")
    return errs


def lint(man):
    pages = sorted(os.path.join(man, p) for p in os.listdir(man) if re.search(r"\.[1-8]$", p))
    r = subprocess.run(["mandoc", "-Tlint", "-Wwarning"] + pages, capture_output=True, text=True)
    return pages, (r.stdout + r.stderr).strip() if r.returncode else ""


# each mutation: a page and a change (regex, replacement); the content check must fail on it
MUTATIONS = [
    ("seamtexd.8", r"^.*max-conns.*\n", ""),
    ("seamtexd.8", r"^\.Sh SIGNALS", r".It Fl \\-no-such-flag\n.Sh SIGNALS"),
    ("seamtex.1", r"^\.It Cm compress.*\n", ""),
    ("seamtex.1", r"^.*retries.*\n", ""),
    ("seamtex.1", r"^\.It Cm compress", r".It Fl \\-no-such-option\n.It Cm compress"),
    ("seamtex-bench.1", r"^\.Sh EXAMPLES", r".It Fl \\-no-such-option\n.Sh EXAMPLES"),
    ("seamtex-bench.1", r"^.*spin-us.*\n", ""),
    ("seamtex-render.1", r"^.*breakdown.*\n", ""),
    ("libseamtex.3", r"^.*stc_job_wait.*\n", ""),
    ("libseamtex.3", r"^.*stc_cluster_rank.*\n", ""),
    ("seamtex-python.3", r"^.*sample_dir.*\n", ""),
    ("seamtex-python.3", r"ChecksumMismatch", "Checksum"),
]


def self_test(h):
    bad = 0
    with tempfile.TemporaryDirectory(prefix="seamtex-checkman-") as tmp:
        for page, pat, rep in MUTATIONS:
            man = os.path.join(tmp, "man")
            shutil.rmtree(man, ignore_errors=True)
            shutil.copytree(os.path.join(ROOT, "man"), man)
            path = os.path.join(man, page)
            text = open(path).read()
            new = re.sub(pat, rep, text, flags=re.M)
            if new == text:
                print(f"check-man self-test: /{pat}/ did not change {page}")
                bad = 1
                continue
            open(path, "w").write(new)
            if not content(man, h):
                print(f"check-man self-test: the check passed on {page} changed by /{pat}/")
                bad = 1
    if not bad:
        print(f"check-man: self-test: each of {len(MUTATIONS)} broken pages is caught")
    return bad


def main(argv):
    if len(argv) == 3 and argv[1] == "--self-test":
        return self_test(gather(argv[2]))
    if len(argv) == 4 and argv[1] == "--no-lint":
        errs = content(argv[2], gather(argv[3]))
        for e in errs:
            print("check-man: " + e)
        return 1 if errs else 0
    if len(argv) != 3:
        print(__doc__.split("\n\n")[0], file=sys.stderr)
        return 2
    pages, lint_out = lint(argv[1])
    h = gather(argv[2])
    errs = content(argv[1], h)
    if lint_out:
        print(lint_out)
        print("check-man: mandoc -Tlint -Wwarning is not clean")
    for e in errs:
        print("check-man: " + e)
    if lint_out or errs:
        return 1
    print(f"check-man: {len(pages)} pages lint-clean (mandoc -Tlint -Wwarning) and true to "
          "--help, client/seamtex.h, client/seamtex_cluster.h, client/seamtex_etcd.h and python/seamtex/__init__.pyi")
    return self_test(h)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
