"""The console sessions of README.md and the pages under docs/: each ```console block is a list of
`$ command` lines, each followed by exactly the output it prints (stdout and stderr, COLUMNS=80).

``tests/test_docs.py`` runs every command and compares. After a change that is meant to alter what
a command prints, ``make transcripts`` (``python tests/transcripts.py --update [PAGE...]``) runs the
sessions the same way and writes what they print back into the pages; read the diff before
committing it: it is the change users will see."""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
CONSOLE = re.compile(r"```console\n(.*?)```", flags=re.DOTALL)


def nav_pages(nav: object) -> list[str]:
    """The pages of mkdocs.yml's nav, in order."""
    if isinstance(nav, str):
        return [nav]
    if isinstance(nav, list):
        return [page for item in nav for page in nav_pages(item)]
    if isinstance(nav, dict):
        return [page for value in nav.values() for page in nav_pages(value)]
    return []


def pages() -> list[Path]:
    """README.md, then every page of the docs in the order its sessions run: the reference pages in
    the nav's order (a page may use a file an earlier one wrote, as README.md's quick start writes
    demo/cal.json), then the recipes (each starts from sample_data/ and writes into its own folder)."""
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"))
    listed = [DOCS / name for name in nav_pages(config["nav"])]
    ordered = [page for page in listed if "recipes" not in page.parts] + [p for p in listed if "recipes" in p.parts]
    return [ROOT / "README.md", *ordered]


def sessions(text: str) -> list[tuple[str, list[str]]]:
    """(command, expected output lines) for each `$` line of every console block of ``text``."""
    out: list[tuple[str, list[str]]] = []
    for block in CONSOLE.findall(text):
        for line in block.splitlines():
            if line.startswith("$ "):
                out.append((line[2:], []))
            else:
                out[-1][1].append(line)
    return out


def prepare(folder: Path) -> Path:
    """A folder like the repo root: sample_data/ and tests/data/ (linked) and an empty demo/."""
    (folder / "sample_data").symlink_to(ROOT / "sample_data")
    (folder / "tests").mkdir()
    (folder / "tests" / "data").symlink_to(ROOT / "tests" / "data")  # the real captures pages read
    (folder / "demo").mkdir()
    return folder


def run(command: str, folder: Path) -> list[str]:
    """What ``command`` prints, run by a shell in ``folder`` with the venv's tumblecal first on PATH."""
    env = dict(os.environ, COLUMNS="80", PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    env.pop("NO_COLOR", None)
    result = subprocess.run(
        command, shell=True, cwd=folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    return [line.rstrip() for line in result.stdout.rstrip("\n").splitlines()]


def rewritten(text: str, folder: Path) -> str:
    """``text`` with each console block's output replaced by what its commands print now."""

    def block(match: re.Match[str]) -> str:
        out = [
            f"$ {command}\n" + "".join(f"{line}\n" for line in run(command, folder))
            for command, _ in sessions(match.group(0))
        ]
        return "```console\n" + "".join(out) + "```"

    return CONSOLE.sub(block, text)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--update", action="store_true", help="write the new output into the pages")
    parser.add_argument("only", nargs="*", help="pages to rewrite (all run, so that files they use exist)")
    args = parser.parse_args()
    changed = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = prepare(Path(tmp))
        for page in pages():
            text = page.read_text(encoding="utf-8")
            new = rewritten(text, folder)
            name = str(page.relative_to(ROOT))
            if new != text and (not args.only or name in args.only):
                changed.append(name)
                if args.update:
                    page.write_text(new, encoding="utf-8")
    verb = "rewrote" if args.update else "differs"
    print("\n".join(f"{verb}: {name}" for name in changed) or "all sessions as written")
    return 1 if changed and not args.update else 0


if __name__ == "__main__":
    sys.exit(main())
