"""The README's quick start for your own photos, run as written on a user's folder of rendered PNGs:
its code block is read from README.md, only the placeholders (the COLMAP model, the photo folders,
the camera) are filled in, and the photos must come back localized."""
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def quick_start_commands():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Localize your own photos", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, re.S).group(1)
    # Join continuation lines, drop comments.
    joined = re.sub(r"\\\n\s*", " ", block)
    return [re.sub(r"\s+#.*$", "", line).strip() for line in joined.splitlines() if line.strip()]


def test_readme_quick_start_localizes_a_users_photos(tmp_path):
    lboost, tiny = os.environ.get("LMB_LBOOST"), os.environ.get("LMB_TINY_DIR")
    if not lboost or not tiny or not (Path(tiny) / "collection" / "sparse").exists():
        pytest.skip("LMB_LBOOST and LMB_TINY_DIR (the tiny world of the ctest fixture lmb_tiny_world) are not available")
    collection = Path(tiny) / "collection"
    # A user's folders: the COLMAP model, the photos it was made from, and new photos to localize.
    shutil.copytree(collection / "sparse", tmp_path / "sparse" / "0")
    shutil.copytree(collection / "images", tmp_path / "photos")
    new = tmp_path / "new_photos"
    new.mkdir()
    queries = sorted((collection / "images" / "query").glob("*.png"))[:4]
    assert queries
    for q in queries:
        shutil.copy(q, new / q.name)
    camera = next(line for line in (collection / "sparse" / "cameras.txt").read_text().splitlines()
                  if line and not line.startswith("#")).split(maxsplit=1)[1]
    commands = quick_start_commands()
    assert [c.split()[1] for c in commands] == ["import", "map", "world", "vocab", "train", "export", "localize",
                                               "scene"]
    env = dict(os.environ, PATH=str(Path(lboost).parent) + os.pathsep + os.environ["PATH"])
    for command in commands:
        # The placeholders: the rendered world is gravity-aligned (+z up) and has no gravity file.
        command = command.replace("--gravity-file gravity.txt", "--up +z")
        command = command.replace("--images DIR", f"--images {new}")
        command = command.replace('"PINHOLE W H fx fy cx cy"', f'"{camera}"')
        command = command.replace("OUT/", "out/")
        subprocess.run(command, shell=True, cwd=tmp_path, env=env, check=True, capture_output=True)
    poses = json.loads((tmp_path / "poses.json").read_text())
    photos = poses["frames"] if "frames" in poses else poses["photos"]
    assert len(photos) == len(queries)
    assert sum(bool(p.get("success")) for p in photos) >= len(queries) // 2, photos
    assert (tmp_path / "out" / "scene" / "sparse" / "images.txt").exists()
    assert (tmp_path / "out" / "scene" / "scene.ply").exists()
