#!/usr/bin/env bash
# Run a command inside a Debian chroot made by tools/matrix.sh, in a private mount namespace, so its bind
# mounts (proc, dev, the repository, the shared folder, the build folder, /tmp) end with the command and
# never outlive it (an `rm -rf build` can then never reach the repository through a mount).
#   in_chroot.sh CHROOT_DIR [--bind DIR]... -- COMMAND [ARGS...]
# The command runs as root in the same working directory, with a Debian PATH and the caller's environment.
set -euo pipefail
if [ -z "${MYOSKIN_IN_NAMESPACE:-}" ]; then
  MYOSKIN_IN_NAMESPACE=1 exec unshare --mount --propagation private -- "$0" "$@"
fi
unset MYOSKIN_IN_NAMESPACE
root="$(cd "$1" && pwd)"; shift
binds=(/tmp)
while [ $# -gt 0 ] && [ "$1" != "--" ]; do
  case "$1" in
    --bind) binds+=("$(cd "$2" && pwd)"); shift 2 ;;
    *) echo "in_chroot.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
[ "${1:-}" = "--" ] && shift
[ $# -gt 0 ] || { echo "in_chroot.sh: no command" >&2; exit 2; }
mount -t proc proc "$root/proc"
mount --rbind /dev "$root/dev"
for d in "${binds[@]}"; do
  mkdir -p "$root$d"
  mount --bind "$d" "$root$d"
done
cwd="$(pwd)"
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin HOME=/root
exec chroot "$root" /bin/bash -c 'cd "$1" 2>/dev/null || cd /; shift; exec "$@"' in_chroot "$cwd" "$@"
