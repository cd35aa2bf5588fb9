#!/usr/bin/env bash
# The README's first command: installs what is missing, builds, makes the Python package
# importable (scripts/python_path.sh), and runs the main job on the embedded default data (a
# rendered self-similar world), printing its result.
#   LMB_PRESET   world preset (default: default)
#   LMB_OUT      output folder (default: out/<preset>)
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
./scripts/build.sh >/dev/null
./scripts/python_path.sh
exec ./jobs/pipeline.sh "${LMB_PRESET:-default}" "${LMB_OUT:-out/${LMB_PRESET:-default}}"
