#!/usr/bin/env bash
# The VM test must fail loudly, never pass silently, when the VM cannot do
# its job.  Runs run-vm.sh in broken set-ups and checks each one exits
# non-zero with the expected reason.
#   tests/vm/test-failure-modes.sh WORKDIR HD_VM_CAN_TEST_EXE
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=$1 exe=$2
mkdir -p "$work"
status=0
expect_fail() { # name reason-regex command...
  local name=$1 reason=$2; shift 2
  local out rc
  out=$("$@" 2>&1); rc=$?
  if [ $rc -ne 0 ] && grep -qE "vm: FAIL: .*($reason)" <<<"$out"; then
    echo "ok: $name -> $(grep -E 'vm: FAIL' <<<"$out" | head -n1)"
  else
    echo "NOT OK: $name: exit $rc, expected a failure matching '$reason'; output:"
    echo "$out" | tail -n 20
    status=1
  fi
}
expect_fail "no QEMU binary" "not found" \
  env HD_QEMU=/nonexistent/qemu-system-x86_64 "$here/run-vm.sh" "$work/noqemu" "$exe"
expect_fail "QEMU cannot start" "QEMU exited with" \
  env HD_QEMU=false "$here/run-vm.sh" "$work/false" "$exe"
expect_fail "VM timeout" "timed out" \
  env HD_VM_TIMEOUT_S=1 "$here/run-vm.sh" "$work/timeout" "$exe"
# QEMU exits 0 after poweroff whatever happened: no verdict must not pass.
expect_fail "guest without the test program" "without a verdict" \
  "$here/run-vm.sh" "$work/noprog"
# --share-host (the 9p exports of the host's root and the output folder):
# refused arguments before any boot, and a guest that cannot use the export
# or whose command fails.
expect_fail "guest command without --share-host" "needs --share-host" \
  "$here/run-vm.sh" "$work/noshare" -- /bin/true
expect_fail "guest argument with a space" "with a space" \
  "$here/run-vm.sh" --share-host "$work/space" -- /bin/echo "two words"
cat >"$work/qemu-without-9p" <<'WRAP'
#!/usr/bin/env bash
# QEMU without run-vm.sh's -virtfs exports: the guest finds no host root.
args=()
while [ $# -gt 0 ]; do
  if [ "$1" = -virtfs ]; then shift 2; continue; fi
  args+=("$1"); shift
done
exec qemu-system-x86_64 "${args[@]}"
WRAP
chmod +x "$work/qemu-without-9p"
expect_fail "no 9p export of the host's root" "cannot mount the host's root" \
  env HD_QEMU="$work/qemu-without-9p" "$here/run-vm.sh" --share-host "$work/no9p" -- /bin/true
expect_fail "the guest command fails" "/bin/false exited with 1" \
  "$here/run-vm.sh" --share-host "$work/cmdfails" -- /bin/false
exit $status
