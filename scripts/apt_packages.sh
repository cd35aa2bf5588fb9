# shellcheck shell=bash
# Sourced by the install scripts: Debian packages installed only when missing (idempotent).
#   missing_packages P...        prints the packages of P that are not installed, one a line
#   apt_install WHO P...         apt-get installs P quietly (sudo when not root), WHO names the caller

missing_packages() {
  local p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"
  done
}

apt_install() {
  local who=$1
  shift
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  echo "$who: installing $*"
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
}
