#!/usr/bin/env bash
# Builds the test VM (build-vm.sh) and boots it under QEMU (TCG, no KVM).
#
#   tests/vm/run-vm.sh OUTDIR [build-vm.sh items: EXECUTABLE | SRC=DEST ...]
#   tests/vm/run-vm.sh --share-host OUTDIR [items...] -- COMMAND [ARGS...]
#
# The guest's /init runs /bin/hd_vm_can_test, which writes the verdict to
# the isa-debug-exit port: QEMU exits 33 (0x10: pass) or 35 (0x11: fail).
# With --share-host, QEMU exports the host's root read-only and the empty
# folder OUTDIR/share writable (virtio 9p), and /init runs COMMAND (a path
# on the host, no spaces in any argument) chrooted into the host's root,
# with OUTDIR/share on /run/hdvm-out; COMMAND's exit status is the verdict.
# Anything else -- QEMU missing, no boot, a timeout, a guest that powered
# off without a verdict (QEMU exits 0 then) -- is a FAILURE with the reason
# and the serial log tail.  The full serial log is OUTDIR/serial.log; the
# wall time of boot + test is OUTDIR/wall_time_s.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
fail() {
  echo "vm: FAIL: $*" >&2
  if [ -s "${log:-/nonexistent}" ]; then
    echo "---- serial log tail ($log)" >&2
    tail -n 40 "$log" >&2
  fi
  exit 1
}
share=()
if [ "${1:-}" = --share-host ]; then share=(--share-host); shift; fi
[ $# -ge 1 ] || fail "usage: $0 [--share-host] OUTDIR [items...] [-- COMMAND...]"
out=$1; shift
items=() guest=()
while [ $# -gt 0 ]; do
  if [ "$1" = -- ]; then shift; guest=("$@"); break; fi
  items+=("$1"); shift
done
[ ${#guest[@]} -eq 0 ] || [ ${#share[@]} -eq 1 ] || fail "a guest COMMAND needs --share-host"
for a in "${guest[@]}"; do
  case $a in *[[:space:]\"]*|'') fail "guest argument '$a': empty or with a space or quote (the kernel command line carries it)" ;; esac
done
mkdir -p "$out"
log=$out/serial.log
rm -f "$log" "$out/wall_time_s"
virtfs=() append="console=ttyS0 quiet panic=-1"
if [ ${#share[@]} -eq 1 ]; then
  # A fresh output folder: nothing of an earlier run can be mistaken for this one's.
  rm -rf "$out/share" && mkdir "$out/share" || fail "cannot create $out/share"
  virtfs=(-virtfs "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap"
          -virtfs "local,path=$(cd "$out/share" && pwd),mount_tag=hdvmout,security_model=none,multidevs=remap")
  [ ${#guest[@]} -eq 0 ] || append="$append -- ${guest[*]}"
fi
timeout_s=${HD_VM_TIMEOUT_S:-180}
qemu=${HD_QEMU:-qemu-system-x86_64}

command -v "$qemu" >/dev/null || fail "$qemu not found (tools/setup installs qemu-system-x86)"
"$here/build-vm.sh" "${share[@]}" "$out" "${items[@]}" || fail "could not build the VM image (see above)"

start=$(date +%s.%N)
# TCG on purpose: with -enable-kvm the guest hung at boot on the CI host.
timeout --kill-after=5 "$timeout_s" "$qemu" -m 512 -smp 1 -nographic -no-reboot -net none \
  -monitor none -serial "file:$log" \
  -kernel "$out/kernel" -initrd "$out/initrd.cpio.gz" \
  -append "$append" "${virtfs[@]}" \
  -device isa-debug-exit,iobase=0xf4,iosize=0x04 </dev/null
rc=$?
end=$(date +%s.%N)
wall=$(echo "$end - $start" | bc 2>/dev/null || awk "BEGIN{print $end - $start}")
echo "$wall" >"$out/wall_time_s"
echo "vm: QEMU exit code $rc after ${wall} s (boot + test, TCG)"
grep -E '^HDVM: (ok  |FAIL|booted|runner|test|VERDICT|insmod|ip link|hd_vm|host root|guest|cannot)' "$log" 2>/dev/null | grep -v '^HDVM: ok  ' || true
echo "vm: $(grep -c '^HDVM: ok  ' "$log" 2>/dev/null || true) checks passed in the guest"

case $rc in
  33) grep -q '^HDVM: VERDICT PASS' "$log" || fail "exit code says pass but the serial log has no PASS verdict"
      echo "vm: PASS"; exit 0 ;;
  35) fail "the guest test reported failures ($(grep -m1 -o 'VERDICT FAIL.*' "$log" | tr -d '\r'); HDVM: FAIL lines above)" ;;
  124|137) fail "VM timed out after ${timeout_s} s (did the kernel boot? is the host very slow?)" ;;
  0)  fail "the guest powered off without a verdict (test program missing or crashed?)" ;;
  *)  fail "QEMU exited with $rc (could not start the VM?)" ;;
esac
