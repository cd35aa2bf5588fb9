"""python/examples/localize_queries.py on the tiny world: the frames `lboost localize` localizes."""
import json
import os
import subprocess
import sys
from pathlib import Path


def test_example_localizes_the_tiny_worlds_query_frames(tiny):
    source = Path(os.environ.get("LMB_SOURCE_DIR", Path(__file__).parents[2]))
    script = source / "python" / "examples" / "localize_queries.py"
    out = subprocess.run([sys.executable, str(script), "--model", str(tiny.model), "--map", str(tiny.map),
                          "--threads", "2"], capture_output=True, text=True, check=True).stdout
    lines = out.strip().split("\n")
    expected = json.loads(tiny.poses.read_text())
    frames = expected["frames"]
    assert len(lines) == len(frames) + 1
    for line, frame in zip(lines, frames):
        assert line.startswith(frame["name"] + (": localized" if frame["success"] else ": not localized")), line
        if frame["success"]:
            assert f"error {frame['position_error_m']:.3f} m {frame['rotation_error_deg']:.2f} deg" in line, line
    summary = expected["summary"]
    assert lines[-1].startswith(f"localized {summary['localized']}/{summary['frames']} query frames"), lines[-1]
