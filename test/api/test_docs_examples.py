"""Every ```python example of docs/api.md and of the README's quick start runs and its
asserts hold (closed forms, the Python and YAML sample being one, contacts, the state round
trip)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
API_DOC = ROOT / "docs" / "api.md"
EXAMPLES = re.findall(r"```python\n(.*?)```", API_DOC.read_text(), flags=re.DOTALL)
README_EXAMPLES = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(),
                             flags=re.DOTALL)


def test_the_doc_has_its_examples() -> None:
    assert len(EXAMPLES) >= 7
    first = EXAMPLES[0].strip().splitlines()
    assert len(first) < 20 and "from_scene(\"sample\")" in EXAMPLES[0]


@pytest.mark.parametrize("number", range(len(EXAMPLES)))
def test_example_runs(number: int) -> None:
    code = compile(EXAMPLES[number], f"{API_DOC.name} example {number + 1}", "exec")
    exec(code, {"__name__": f"example_{number + 1}"})


def test_the_readme_quick_start_runs() -> None:
    assert len(README_EXAMPLES) == 1
    exec(compile(README_EXAMPLES[0], "README.md quick start", "exec"), {"__name__": "readme"})
