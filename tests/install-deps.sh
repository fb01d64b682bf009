#!/bin/sh
# install-deps.sh PACKAGE...: installs the Debian packages that are missing.
# As root it runs apt-get; otherwise it prints the exact command and fails, so
# `make test` and `make demo` either have what they need or say what to run.
set -u
missing=""
for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
[ -z "$missing" ] && exit 0
if [ "$(id -u)" = 0 ]; then
    echo "install-deps: installing$missing" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >&2 && apt-get install -y -qq --no-install-recommends $missing >&2 && exit 0
    echo "install-deps: apt-get failed for$missing" >&2
    exit 1
fi
echo "install-deps: missing Debian packages; run as root:" >&2
echo "  apt-get update && apt-get install -y$missing" >&2
exit 1
