"""Every ```python example of docs/api.md runs and its asserts hold (closed forms, the
Python and YAML sample being one, contacts, the state round trip)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

API_DOC = Path(__file__).resolve().parents[2] / "docs" / "api.md"
EXAMPLES = re.findall(r"```python\n(.*?)```", API_DOC.read_text(), flags=re.DOTALL)


def test_the_doc_has_its_examples() -> None:
    assert len(EXAMPLES) >= 7
    first = EXAMPLES[0].strip().splitlines()
    assert len(first) < 20 and "from_scene(\"sample\")" in EXAMPLES[0]


@pytest.mark.parametrize("number", range(len(EXAMPLES)))
def test_example_runs(number: int) -> None:
    code = compile(EXAMPLES[number], f"{API_DOC.name} example {number + 1}", "exec")
    exec(code, {"__name__": f"example_{number + 1}"})
