#!/usr/bin/env bash
# ensure_debian.sh COMMAND PACKAGE [COMMAND PACKAGE ...]: install each Debian PACKAGE whose COMMAND is missing
# (as root, or through sudo). Fails loudly, naming the package, when it cannot.
set -euo pipefail
missing=()
while [ $# -ge 2 ]; do
  command -v "$1" > /dev/null 2>&1 || missing+=("$2")
  shift 2
done
[ ${#missing[@]} -eq 0 ] && exit 0
if [ "$(id -u)" -eq 0 ]; then SUDO=(); elif command -v sudo > /dev/null; then SUDO=(sudo -n); else
  echo "missing Debian packages: ${missing[*]}; install them (apt-get install ${missing[*]}) or run as root" >&2; exit 1
fi
echo "Installing Debian packages: ${missing[*]} ..." >&2
log=$(mktemp)
if ! { "${SUDO[@]}" apt-get update -q && DEBIAN_FRONTEND=noninteractive "${SUDO[@]}" apt-get install -y -q \
       --no-install-recommends "${missing[@]}"; } > "$log" 2>&1; then
  tail -n 30 "$log" >&2
  echo "could not install Debian packages: ${missing[*]}" >&2; exit 1
fi
rm -f "$log"
