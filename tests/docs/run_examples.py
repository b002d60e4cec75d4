#!/usr/bin/env python3
"""Runs the examples of README.md and docs/*.md, so that none of them goes stale.

Usage:
    python3 tests/docs/run_examples.py --bin DIR [--pythonpath DIR] [--keep] [FILE.md ...]

  --bin DIR          a folder holding the `gcmap` binary; it goes first on PATH
  --pythonpath DIR   the folder holding the `gcmap` Python package (build/python); set as PYTHONPATH
  --python EXE       the interpreter of ```python blocks (default /usr/bin/python3, Debian's, with NumPy)
  --keep             keep the temporary folders and print where they are
  FILE.md ...        only these files (default: README.md, then docs/*.md in name order)

Rules, per fenced code block (the word after the opening fence names its kind):
  ```sh       run with bash under `set -euo pipefail`
  ```python   run with the --python interpreter
  ```console, ```text, and any other kind (yaml, json, cpp, none): shown, never run. Use console
              for output samples and for commands that need data the reader has (a KITTI folder).
  ```bash, ```shell, ```py, ```python3: an error. They look runnable but would not run; write sh,
              python or console.
  Setup rule: a ```sh block whose every command is one that CI runs itself (.ci/run:
              ./scripts/setup.sh, ctest, ./scripts/sanitize.sh, ./scripts/fuzz_smoke.sh) is skipped;
              building and the test suite are not examples to run inside a test of the test suite.

Every file's blocks run in order in one fresh temporary folder (a later block may use what an
earlier one wrote), with --bin first on PATH and PYTHONPATH set to --pythonpath.

Besides the blocks, every file's links must stay inside the repository and name a file or folder
that exists (web links and #anchors are not checked), and README.md must keep to 220 lines of at
most 400 characters.

Prints each block's file and line; exits 1 naming the file and line of the first failing block.
Standard library only.
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
RUN_KINDS = {"sh", "python"}
REJECTED_KINDS = {"bash", "shell", "zsh", "py", "python3"}
# The commands CI runs itself (.ci/run); a block made only of these is skipped.
CI_COMMANDS = ("./scripts/setup.sh", "ctest", "./scripts/sanitize.sh", "./scripts/fuzz_smoke.sh")
README_MAX_LINES = 220
README_MAX_LINE_CHARS = 400
BLOCK_TIMEOUT_S = 600


class Block:
    def __init__(self, path, line, kind, text):
        self.path, self.line, self.kind, self.text = path, line, kind, text

    @property
    def where(self):
        return f"{os.path.relpath(self.path, ROOT)}:{self.line}"


def extract_blocks(path):
    """The fenced code blocks of a Markdown file: (line of the opening fence, kind, text)."""
    blocks, open_fence = [], None
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    for number, line in enumerate(lines, start=1):
        m = re.match(r"^ {0,3}(`{3,}|~{3,})(.*)$", line)
        if open_fence is None:
            if m:
                fence, info = m.group(1), m.group(2).strip()
                kind = info.split()[0].lower() if info else ""
                open_fence, start, kind_of, body = fence, number, kind, []
            continue
        if m and m.group(1)[0] == open_fence[0] and len(m.group(1)) >= len(open_fence) and not m.group(2).strip():
            blocks.append(Block(path, start, kind_of, "\n".join(body) + "\n"))
            open_fence = None
        else:
            body.append(line)
    if open_fence is not None:
        raise SystemExit(f"{os.path.relpath(path, ROOT)}:{start}: code block is never closed")
    return blocks


def commands_of(text):
    """The command lines of a shell block: comments, blank lines and continuations left out."""
    out, continued = [], False
    for raw in text.split("\n"):
        line = raw.strip()
        if continued:
            continued = line.endswith("\\")
            continue
        continued = line.endswith("\\")
        if line and not line.startswith("#"):
            out.append(line)
    return out


def is_ci_setup_block(block):
    """The setup rule: every command of the block is one that CI runs itself."""
    cmds = commands_of(block.text)
    return bool(cmds) and all(any(c == x or c.startswith(x + " ") for x in CI_COMMANDS) for c in cmds)


def check_links(path):
    """Problems with the links of one file: leaving the repository, or naming nothing."""
    problems = []
    with open(path, encoding="utf-8") as f:
        text = f.read()
    # Links outside code: drop fenced blocks and inline code first.
    text_no_code = re.sub(r"(?ms)^ {0,3}(`{3,}|~{3,}).*?^ {0,3}\1\s*$", lambda m: "\n" * m.group(0).count("\n"), text)
    for number, line in enumerate(text_no_code.split("\n"), start=1):
        line = re.sub(r"`[^`]*`", "", line)
        for target in re.findall(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", line):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
                continue  # a web address or an anchor in this file
            file_part = target.split("#", 1)[0]
            resolved = os.path.normpath(os.path.join(os.path.dirname(path), file_part))
            where = f"{os.path.relpath(path, ROOT)}:{number}"
            if os.path.isabs(file_part) or os.path.relpath(resolved, ROOT).startswith(".."):
                problems.append(f"{where}: link leaves the repository: {target}")
            elif not os.path.exists(resolved):
                problems.append(f"{where}: link names nothing: {target}")
    return problems


def check_readme(path):
    problems = []
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    if len(lines) > README_MAX_LINES:
        problems.append(f"README.md: {len(lines)} lines, at most {README_MAX_LINES}")
    for number, line in enumerate(lines, start=1):
        if len(line) > README_MAX_LINE_CHARS:
            problems.append(f"README.md:{number}: {len(line)} characters, at most {README_MAX_LINE_CHARS}")
    return problems


def run_block(block, workdir, env, python):
    if block.kind == "sh":
        argv = ["bash", "-c", "set -euo pipefail\n" + block.text]
    else:
        script = os.path.join(workdir, f".block_{block.line}.py")
        with open(script, "w", encoding="utf-8") as f:
            f.write(block.text)
        argv = [python, script]
    started = time.monotonic()
    try:
        p = subprocess.run(argv, cwd=workdir, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           timeout=BLOCK_TIMEOUT_S, stdin=subprocess.DEVNULL)
        code, output = p.returncode, p.stdout.decode("utf-8", "replace")
    except subprocess.TimeoutExpired as e:
        code, output = "timeout", (e.stdout or b"").decode("utf-8", "replace") + f"\n(killed after {BLOCK_TIMEOUT_S} s)"
    return code, output, time.monotonic() - started


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True, help="folder holding the gcmap binary")
    ap.add_argument("--pythonpath", default="", help="folder holding the gcmap Python package")
    ap.add_argument("--python", default="/usr/bin/python3", help="interpreter of python blocks")
    ap.add_argument("--keep", action="store_true", help="keep the temporary folders")
    ap.add_argument("files", nargs="*", help="Markdown files (default: README.md and docs/*.md)")
    args = ap.parse_args()

    bin_dir = os.path.abspath(args.bin)
    if not os.access(os.path.join(bin_dir, "gcmap"), os.X_OK):
        sys.exit(f"--bin {args.bin}: no executable gcmap there")
    files = [os.path.abspath(f) for f in args.files]
    if not files:
        docs = os.path.join(ROOT, "docs")
        files = [os.path.join(ROOT, "README.md")] + sorted(
            os.path.join(docs, n) for n in (os.listdir(docs) if os.path.isdir(docs) else []) if n.endswith(".md"))

    problems = []
    for path in files:
        problems += check_links(path)
        if os.path.basename(path) == "README.md" and os.path.dirname(path) == ROOT:
            problems += check_readme(path)
    if problems:
        print("\n".join(problems))
        print(f"FAILED: {problems[0].split(': ')[0]}")
        return 1

    env = dict(os.environ)
    env["PATH"] = bin_dir + os.pathsep + env.get("PATH", "")
    env["PYTHONPATH"] = os.path.abspath(args.pythonpath) if args.pythonpath else ""
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    env["MPLBACKEND"] = "Agg"

    total_started, counts = time.monotonic(), {"run": 0, "shown": 0, "skipped": 0}
    for path in files:
        blocks = extract_blocks(path)
        workdir = tempfile.mkdtemp(prefix="gcmap_docs_" + os.path.splitext(os.path.basename(path))[0] + "_")
        try:
            for block in blocks:
                if block.kind in REJECTED_KINDS:
                    print(f"{block.where}: ```{block.kind} block: write sh or python (run) or console (shown)")
                    print(f"FAILED: {block.where}")
                    return 1
                if block.kind not in RUN_KINDS:
                    counts["shown"] += 1
                    continue
                if block.kind == "sh" and is_ci_setup_block(block):
                    print(f"{block.where}: {'sh':<7}skipped (setup rule: CI runs these commands itself)")
                    counts["skipped"] += 1
                    continue
                print(f"{block.where}: {block.kind:<7}", end="", flush=True)
                code, output, seconds = run_block(block, workdir, env, args.python)
                if code != 0:
                    print(f"FAILED (exit {code}, {seconds:.1f} s)")
                    print("---- block ----\n" + block.text.rstrip())
                    print("---- output (last 60 lines) ----\n" + "\n".join(output.rstrip().split("\n")[-60:]))
                    print(f"FAILED: {block.where} (in {workdir})")
                    args.keep = True
                    return 1
                print(f"ok ({seconds:.1f} s)")
                counts["run"] += 1
        finally:
            if args.keep:
                print(f"  ({os.path.relpath(path, ROOT)} ran in {workdir})")
            else:
                shutil.rmtree(workdir, ignore_errors=True)
    print(f"docs examples: {counts['run']} blocks run, {counts['skipped']} skipped by the setup rule, "
          f"{counts['shown']} shown only; {len(files)} files, {time.monotonic() - total_started:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
