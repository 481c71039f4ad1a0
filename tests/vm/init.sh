#!/bin/sh
# /init of the SocketCAN test VM (busybox).  Loads the modules
# (/etc/hdvm-modules), creates vcan0 and runs the test:
#  - no arguments: /bin/hd_vm_can_test, which reports the verdict through
#    the isa-debug-exit device and an "HDVM: VERDICT" line itself;
#  - arguments (the kernel command line after "--", run-vm.sh --share-host):
#    the host's root is mounted read-only at /host (9p), with the guest's
#    /proc, /sys, /dev, a tmpfs on /run (not /tmp: a checkout under the
#    host's /tmp must stay visible) and the writable output folder on
#    /run/hdvm-out; the arguments run as a command chrooted there, and its
#    exit status is the verdict (0 PASS, anything else FAIL).
export PATH=/bin
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev 2>/dev/null
echo "HDVM: booted kernel $(uname -r), guest uptime $(cut -d" " -f1 /proc/uptime) s"

# The verdict for run-vm.sh: a line on the console, then 0x10 (pass) or
# 0x11 (fail) to the isa-debug-exit port 0xf4 through /dev/port.
verdict() { # PASS|FAIL reason
  echo "HDVM: VERDICT $1 ($2)"
  sleep 0.2   # the console line must be out before QEMU exits
  if [ "$1" = PASS ]; then code='\020'; else code='\021'; fi
  printf "$code" | dd of=/dev/port bs=1 seek=244 count=1 conv=notrunc 2>/dev/null
  echo "HDVM: isa-debug-exit not available"
}

for m in $(cat /etc/hdvm-modules); do
  insmod /lib/modules/$m.ko || echo "HDVM: insmod $m failed"
done
ip link add dev vcan0 type vcan || echo "HDVM: ip link add vcan0 failed"
ip link set up vcan0 || echo "HDVM: ip link set up vcan0 failed"
# A classic-only interface (MTU 16) for the backend's FD capability check.
ip link add dev vcan1 type vcan && ip link set vcan1 mtu 16 && ip link set up vcan1 \
  || echo "HDVM: classic-only vcan1 setup failed"

if [ $# -gt 0 ]; then
  opts=trans=virtio,version=9p2000.L,msize=262144
  mkdir -p /host
  # cache=loose: the host's tree does not change under a test run, and
  # caching its metadata halves Python's start-up over 9p under TCG.
  if ! mount -t 9p -o $opts,ro,cache=loose hostroot /host; then
    verdict FAIL "cannot mount the host's root (9p tag hostroot): run-vm.sh --share-host?"
  elif ! { mount -t proc proc /host/proc && mount -t sysfs sysfs /host/sys &&
           mount -t devtmpfs devtmpfs /host/dev && mount -t tmpfs tmpfs /host/run &&
           mkdir /host/run/hdvm-out && mount -t 9p -o $opts hdvmout /host/run/hdvm-out; }; then
    verdict FAIL "cannot mount /proc, /sys, /dev, /run or the output folder in /host"
  else
    echo "HDVM: host root on /host, guest uptime $(cut -d" " -f1 /proc/uptime) s; running $*"
    chroot /host /usr/bin/env -i PATH=/usr/local/bin:/usr/bin:/bin:/usr/sbin:/sbin \
      HOME=/run TMPDIR=/run LANG=C.UTF-8 PYTHONDONTWRITEBYTECODE=1 OPENBLAS_NUM_THREADS=1 "$@"
    rc=$?
    sync
    umount /host/run/hdvm-out
    echo "HDVM: guest uptime at the end $(cut -d" " -f1 /proc/uptime) s"
    if [ $rc -eq 0 ]; then verdict PASS "$1 exited with 0"; else verdict FAIL "$1 exited with $rc"; fi
  fi
elif [ -x /bin/hd_vm_can_test ]; then
  /bin/hd_vm_can_test
  echo "HDVM: hd_vm_can_test exited with $?"
else
  echo "HDVM: VERDICT FAIL (no /bin/hd_vm_can_test in the image)"
fi
echo "HDVM: guest uptime at poweroff $(cut -d" " -f1 /proc/uptime) s"
poweroff -f
