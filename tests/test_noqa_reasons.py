"""Every ``# noqa`` of the project names the rules it silences and says why, after ``--``.

ruff checks that each marker is needed and names an enabled rule (RUF100, pyproject.toml); the reason is ours.
"""
from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("cli", "experiments", "fpp", "graph", "messages", "models", "nodes", "sim", "tools", "tests", "benchmarks",
           "examples")
MARKER = re.compile(r"#\s*noqa\b(?P<rest>.*)$")
WITH_REASON = re.compile(r"^: [A-Z]+[0-9]+(, [A-Z]+[0-9]+)* -- \S")


def test_every_noqa_names_its_rules_and_says_why():
    bare = []
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            tokens = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
            for token in tokens:
                found = MARKER.search(token.string) if token.type == tokenize.COMMENT else None
                if found and not WITH_REASON.match(found["rest"]):
                    bare.append(f"  {path.relative_to(ROOT)}:{token.start[0]}: {token.line.strip()}")
    assert not bare, "write '# noqa: CODE -- why' (docs/architecture.md, Style):\n" + "\n".join(bare)
