#!/usr/bin/env bash
# Times the README's first command on a fresh Debian 12 root (docs/testing.md, "The first
# command"): debootstrap a minimal bookworm into DIR, give it what a new machine brings (g++,
# cmake, make, git, python3), clone this repository's HEAD into it and run, under chroot,
#   time scripts/run_case.sh cases/first_link optimize
# Needs root, debootstrap (installed from Debian if missing) and the network to Debian's mirror.
#   scripts/bench/fresh_machine.sh [DIR]     # default /var/tmp/flexopt-fresh; removed first
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
dir="${1:-/var/tmp/flexopt-fresh}"
[ "$(id -u)" -eq 0 ] || { echo "fresh_machine.sh: needs root (debootstrap, chroot)" >&2; exit 2; }
command -v debootstrap >/dev/null || { apt-get update -qq && apt-get install -y -qq debootstrap; }
mounts=(proc sys dev dev/pts dev/shm)
unmount() {
  for ((i = ${#mounts[@]} - 1; i >= 0; i--)); do
    mountpoint -q "$dir/${mounts[i]}" && umount "$dir/${mounts[i]}"
  done
  return 0
}
trap unmount EXIT
if [ -d "$dir" ]; then unmount; rm -rf "$dir"; fi
echo "fresh_machine: debootstrap bookworm into $dir"
debootstrap --variant=minbase bookworm "$dir" http://deb.debian.org/debian >"$dir.debootstrap.log"
if [ -f /etc/apt/sources.list.d/debian.sources ]; then
  rm -f "$dir/etc/apt/sources.list"
  cp /etc/apt/sources.list.d/debian.sources "$dir/etc/apt/sources.list.d/"
fi
cp /etc/resolv.conf "$dir/etc/"
for m in proc sys dev dev/pts; do mount --bind "/$m" "$dir/$m"; done
mkdir -p "$dir/dev/shm" && mount -t tmpfs tmpfs "$dir/dev/shm"
chroot "$dir" env DEBIAN_FRONTEND=noninteractive bash -c \
  'apt-get update -qq && apt-get install -y -qq --no-install-recommends g++ cmake make git python3 ca-certificates' \
  >"$dir.base.log"
git clone -q "$root" "$dir/root/flexopt"
echo "fresh_machine: the first command (log: $dir/root/first.log)"
chroot "$dir" env -i HOME=/root PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
  bash -c 'cd /root/flexopt && start=$(date +%s) &&
           scripts/run_case.sh cases/first_link optimize >/root/first.log 2>&1;
           rc=$?; echo "fresh_machine: rc $rc, $(( $(date +%s) - start )) s in all"; exit $rc'
grep -E "Start-Date|End-Date" "$dir/var/log/apt/history.log" | tail -2 | sed 's/^/fresh_machine: apt /'
