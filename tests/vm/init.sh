#!/bin/sh
# /init of the SocketCAN test VM (busybox).  Loads the CAN modules, creates
# vcan0 and runs /bin/hd_vm_can_test, which reports the verdict through the
# isa-debug-exit device and an "HDVM: VERDICT" line on the serial console.
export PATH=/bin
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev 2>/dev/null
echo "HDVM: booted kernel $(uname -r), guest uptime $(cut -d" " -f1 /proc/uptime) s"
for m in can-dev vcan can can-raw; do
  insmod /lib/modules/$m.ko || echo "HDVM: insmod $m failed"
done
ip link add dev vcan0 type vcan || echo "HDVM: ip link add vcan0 failed"
ip link set up vcan0 || echo "HDVM: ip link set up vcan0 failed"
# A classic-only interface (MTU 16) for the backend's FD capability check.
ip link add dev vcan1 type vcan && ip link set vcan1 mtu 16 && ip link set up vcan1 \
  || echo "HDVM: classic-only vcan1 setup failed"
if [ -x /bin/hd_vm_can_test ]; then
  /bin/hd_vm_can_test
  echo "HDVM: hd_vm_can_test exited with $?"
else
  echo "HDVM: VERDICT FAIL (no /bin/hd_vm_can_test in the image)"
fi
echo "HDVM: guest uptime at poweroff $(cut -d" " -f1 /proc/uptime) s"
poweroff -f
