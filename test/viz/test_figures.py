"""The README shows every shipped scene as an animation of its whole scripted run, kept
small (scripts/scene_figures.sh draws them at 10 frames per sim second)."""
from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("matplotlib", reason="matplotlib is not installed (the viz extra)")
pytest.importorskip("PIL", reason="Pillow is not installed (the viz extra)")
from PIL import Image  # noqa: E402

from hecker_dynamics.scene import load_scene, shipped_scenes  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


@pytest.mark.parametrize("name", shipped_scenes())
def test_each_scene_has_its_animation_in_the_readme(name):
    path = ROOT / "docs" / "figures" / f"{name}.gif"
    row = next(line for line in README.splitlines() if line.startswith(f"| `{name}`"))
    assert f"(docs/figures/{name}.gif)" in row
    assert path.stat().st_size < 400_000
    with Image.open(path) as gif:
        assert gif.n_frames == round(load_scene(name).duration_ns * 10 / 1e9)
        assert gif.info["duration"] == 100
