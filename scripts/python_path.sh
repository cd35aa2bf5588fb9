#!/usr/bin/env bash
# Makes `import landmarkboost` work from any new shell: writes landmarkboost.pth, holding the path
# of this build's package folder (<build>/python), into the user site-packages folder of the
# interpreter the build compiled the package for (Python3_EXECUTABLE in <build>/CMakeCache.txt,
# /usr/bin/python3 by default), then imports the package from a clean environment to check.
# Idempotent; run by scripts/run_main.sh. Undo: delete the .pth file it names.
#   LMB_BUILD_DIR   build folder (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${LMB_BUILD_DIR:-build}
if [ ! -d "$build_dir/python/landmarkboost" ]; then
  echo "python_path: no $build_dir/python/landmarkboost (built with -DLMB_BUILD_PYTHON=OFF?); nothing done"
  exit 0
fi
package_dir=$(cd "$build_dir/python" && pwd)
python=$(sed -n 's/^Python3_EXECUTABLE:[A-Z]*=//p' "$build_dir/CMakeCache.txt")
if [ "$("$python" -c 'import site; print(site.ENABLE_USER_SITE)')" != "True" ]; then
  echo "python_path: $python has no user site-packages (a virtual environment?): use PYTHONPATH=$package_dir"
  exit 0
fi
site=$("$python" -m site --user-site)
mkdir -p "$site"
echo "$package_dir" > "$site/landmarkboost.pth"
# A fresh environment: only HOME and a system PATH, no PYTHONPATH.
env -i HOME="$HOME" PATH=/usr/local/bin:/usr/bin:/bin "$python" -c \
  'import landmarkboost, sys; print("python_path: import landmarkboost works in", sys.executable, "(" + landmarkboost.__file__ + ")")'
echo "python_path: $site/landmarkboost.pth -> $package_dir"
# Another python3 first on PATH (pyenv, conda...) sees the same .pth if it is the same minor
# version, but may lack numpy: say so now rather than at the user's first import.
other=$(command -v python3 || true)
if [ -n "$other" ] && [ "$(readlink -f "$other")" != "$(readlink -f "$python")" ]; then
  if ! "$other" -c 'import landmarkboost' >/dev/null 2>&1; then
    echo "python_path: note: python3 on PATH is $other, which cannot import landmarkboost" \
         "($("$other" -c 'import landmarkboost' 2>&1 | tail -1 | cut -c1-120)); use $python"
  fi
fi
