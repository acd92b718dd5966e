#!/bin/sh
# Runs inside the systemd-under-UML guest (ecu-test-probe.service) and records what systemd did
# with ecu-daemon@can0.service (the template unit's instance for can0); the host-side test reads $OUT and judges. Every wait is bounded.
# Ends the guest with a forced poweroff whatever happens.
OUT=/opt/ecu-test/out
UNIT=ecu-daemon@can0.service
mkdir -p "$OUT"
exec > "$OUT/probe.log" 2>&1
trap 'echo "probe: finished"; sync; systemctl poweroff --force --force' EXIT

prop() { systemctl show -P "$1" "$UNIT"; }
# wait_for SECONDS COMMAND...: poll every 0.2 s until COMMAND succeeds; 1 on time-out
wait_for() {
    n=$(( $1 * 5 )); shift
    while [ "$n" -gt 0 ]; do
        "$@" && return 0
        sleep 0.2; n=$((n - 1))
    done
    "$@"
}
is_active() { [ "$(prop ActiveState)" = active ]; }
restarted() { [ "$(prop NRestarts)" -ge 1 ]; }
tx_lines() { [ "$(wc -l < "$OUT/can0-tx.log" 2>/dev/null || echo 0)" -gt "$1" ]; }
mono() { cut -d' ' -f1 /proc/uptime; }

echo "probe: started at $(mono)"
# 1. The service starts when can0 appears and is 'active' only once it sent READY=1.
#    (PID 1 logs every notification at debug level, switched on before can0 existed.)
wait_for 150 is_active; echo $? > "$OUT/active.rc"
systemd-analyze log-level info
systemctl show "$UNIT" > "$OUT/show-start.txt"
journalctl -b -o short-monotonic --no-pager _PID=1 | grep -F "$UNIT" > "$OUT/pid1-start.txt"
ip -details -statistics link show can0 > "$OUT/can0-link.txt" 2>&1
networkctl status can0 --no-pager > "$OUT/networkctl.txt" 2>&1
systemctl status systemd-networkd --no-pager > "$OUT/networkd-status.txt" 2>&1

# 2. Outputs flow onto can0 (the emulated adapter logs what the host transmits).
wait_for 60 tx_lines 300; echo $? > "$OUT/tx.rc"

# 3. Freeze the main process: the watchdog (WatchdogSec=) must kill and restart it.
PID=$(prop MainPID); echo "$PID" > "$OUT/frozen.pid"
echo "probe: SIGSTOP $PID at $(mono)"
kill -STOP "$PID"
wait_for 30 restarted; echo $? > "$OUT/restart.rc"
echo "probe: NRestarts=$(prop NRestarts) at $(mono)"
wait_for 150 is_active; echo $? > "$OUT/active-again.rc"
systemctl show "$UNIT" > "$OUT/show-restarted.txt"
N1=$(wc -l < "$OUT/can0-tx.log")
wait_for 60 tx_lines $((N1 + 300)); echo $? > "$OUT/tx-again.rc"

# 4. Static checks of the unit as installed.
systemd-analyze security "$UNIT" --no-pager > "$OUT/security.txt" 2>&1
systemd-analyze verify "$UNIT" > "$OUT/verify.txt" 2>&1; echo $? > "$OUT/verify.rc"

# 5. A clean stop: SIGTERM, exit status 0, within TimeoutStopSec.
T0=$(mono); systemctl stop "$UNIT"; T1=$(mono)
echo "$T0 $T1" > "$OUT/stop-times.txt"
systemctl show "$UNIT" > "$OUT/show-stopped.txt"
journalctl -b -o short-monotonic --no-pager -u "$UNIT" > "$OUT/journal-unit.txt"
journalctl -b -o short-monotonic --no-pager > "$OUT/journal-all.txt"
cp /opt/ecu-test/out/slcan-events.json "$OUT/slcan-events-final.json" 2>/dev/null
echo done > "$OUT/probe.done"
