"""Without rosbags (a ROS machine need not have it) the tests that need it skip with the
reason, at collection or while they run, and the others run: none errors
(test/optional_modules.py). Checked in a child pytest with rosbags hidden (HECKER_TEST_HIDE)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from optional_modules import SkipWithoutModule

ROOT = Path(__file__).resolve().parents[1]


def test_an_import_of_a_missing_module_skips_the_importing_test():
    finder = SkipWithoutModule({"no_such_module_here": "no_such_module_here is not installed"})
    sys.meta_path.insert(0, finder)
    try:
        with pytest.raises(pytest.skip.Exception, match="no_such_module_here is not installed"):
            import no_such_module_here.sub  # noqa: F401
        import json  # another module imports as before
        assert json.loads("1") == 1
    finally:
        sys.meta_path.remove(finder)


def test_without_rosbags_its_tests_skip_with_the_reason_and_the_rest_run():
    files = ["test/bags/test_bags.py", "test/batch/test_batch_table.py", "test/test_cli.py",
             "test/fuzz/test_fuzz_scenes.py", "test/ros/test_mapping.py"]
    # The package as this run imports it, with this run's environment: where it is
    # installed, which colcon puts on PYTHONPATH (so not -I, which drops it), and the
    # shipped scenes, which a ROS machine finds through the ament index; -P keeps the
    # source tree off the path. No plugins but pytest's own: a ROS machine's launch_testing
    # plugin turns one module's skip into the whole run's.
    env = dict(os.environ, HECKER_TEST_HIDE="rosbags", PYTEST_DISABLE_PLUGIN_AUTOLOAD="1")
    done = subprocess.run([sys.executable, "-s", "-P", "-m", "pytest", "-q", "-rs", "-p",
                           "no:cacheprovider", *files], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
    summary = done.stdout.strip().splitlines()[-1]
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "error" not in summary and "failed" not in summary, summary
    assert " passed" in summary  # test_mapping's cases without rosbags messages ran
    skipped = [line for line in done.stdout.splitlines() if line.startswith("SKIPPED")]
    for name in files[:4]:  # each of these needs rosbags whole
        assert any("rosbags is not installed" in line and f"imported from {name}:" in line
                   for line in skipped), (name, skipped)
