#!/bin/sh
# PID 1 of the share-the-host's-files UML guest (hostfs root = the host's /).
#
# Brings up the kernel CAN stack and vcan0, runs one job, records its exit status, powers off.
# Environment (from the kernel command line, see boot.py):
#   ECU_UML_OUT     host directory for results (visible here because / is the host's /)
#   ECU_UML_PYTHON  the test environment's interpreter, e.g. <venv>/bin/python (same files here)
#   ECU_UML_RUN     the guest-side program to run with the python, e.g. tools/uml/guest_replay.py
#   ECU_UML_JOB     its argument (a JSON job file)
# Nothing is mounted over /tmp: a tmpfs there would hide the host's /tmp and our results with it.
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
OUT=${ECU_UML_OUT:-/tmp}
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mkdir -p /dev/pts /dev/shm
mount -t devpts -o gid=5,mode=620,ptmxmode=666 devpts /dev/pts
mount -t tmpfs -o mode=1777 tmpfs /dev/shm
hostname uml-ecu
# Socket receive buffers for ~8 s of this bus instead of ~0.3 s: on a loaded host the whole guest
# is descheduled for a second or more, and a CAN socket that overflows meanwhile drops frames the
# drive never lost (the daemon would rightly count them as counter errors). Every frame waits.
echo 8388608 > /proc/sys/net/core/rmem_default
echo 8388608 > /proc/sys/net/core/rmem_max

M=/usr/lib/uml/modules/$(uname -r)/kernel
status=0
for ko in net/can/can.ko net/can/can-raw.ko drivers/net/can/dev/can-dev.ko drivers/net/can/vcan.ko \
          net/can/can-bcm.ko drivers/net/can/slcan/slcan.ko; do   # can-dev before vcan/slcan
    insmod "$M/$ko" || status=1
done
ip link set lo up
ip link add dev vcan0 type vcan && ip link set up vcan0 || status=1
ip -details link show vcan0 > "$OUT/guest-net.txt" 2>&1
echo "$status" > "$OUT/guest-modules.rc"

if [ "$status" = 0 ] && [ -n "$ECU_UML_RUN" ]; then
    cd "${ECU_UML_CWD:-/}"
    "$ECU_UML_PYTHON" "$ECU_UML_RUN" "$ECU_UML_JOB" > "$OUT/guest-run.log" 2>&1
    echo $? > "$OUT/guest-run.rc"
fi
sync
halt -f
