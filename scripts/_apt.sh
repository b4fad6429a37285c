# Sourced by the scripts/setup_*.sh that need Debian packages. Defines
# `apt_ensure NAME CHECK PACKAGE...`: nothing to do when the function CHECK succeeds; otherwise
# install the packages (root only; others are told the command) and check again.

apt_ensure() {
  local name=$1 check=$2
  shift 2
  if "$check"; then
    return 0
  fi
  if ((EUID != 0)); then
    echo "$name: missing packages; installing them needs root:" >&2
    echo "  apt-get install $*" >&2
    return 1
  fi
  echo "$name: installing $*"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "$@" >/dev/null
  "$check" || { echo "$name: still incomplete after installing $*" >&2; return 1; }
}
