#!/bin/sh
# Build (once) the minimal Debian root filesystem the systemd-under-UML tests boot.
#
#   tools/uml/build_rootfs.sh [ROOTFS]        default: /var/cache/ecu-daemon-uml/rootfs
#
# debootstrap --variant=minbase with systemd, udev, iproute2, can-utils, python3 and kmod; the UML
# kernel's modules copied in (depmod'ed so `modprobe vcan` works); a virtual environment at
# /opt/ecu-daemon/venv with our runtime dependencies from PyPI (Debian's python3, as on a vehicle
# computer). Our own package is NOT baked in: the test installs the current wheel on every run.
# Idempotent: a stamp file records what was built; a changed recipe or dependency list rebuilds.
# Needs root, debootstrap and network access to the Debian mirror and PyPI. Takes ~1-2 minutes.
set -eu
ROOTFS=${1:-/var/cache/ecu-daemon-uml/rootfs}
HERE=$(cd "$(dirname "$0")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
RECIPE=5
PKGS=systemd,systemd-sysv,udev,dbus,iproute2,can-utils,python3,python3-venv,kmod,procps
DEPS=$(python3 -c 'import tomllib,sys; print(" ".join(tomllib.load(open(sys.argv[1],"rb"))["project"]["dependencies"]))' \
       "$REPO/pyproject.toml")
UMLVER=$(ls /usr/lib/uml/modules | sort | tail -n 1)
WANT="recipe=$RECIPE pkgs=$PKGS uml=$UMLVER deps=$DEPS"

if [ -f "$ROOTFS/.ecu-rootfs-stamp" ] && [ "$(cat "$ROOTFS/.ecu-rootfs-stamp")" = "$WANT" ]; then
    echo "rootfs up to date: $ROOTFS"
    exit 0
fi

# The mirror apt already uses here (deb822 or one-line sources), else Debian's default.
MIRROR=$(grep -h -o -E '^(URIs:|deb) +https?://[^ ]+' /etc/apt/sources.list.d/*.sources /etc/apt/sources.list \
         2>/dev/null | grep -v security | head -n 1 | awk '{print $2}')
MIRROR=${MIRROR:-http://deb.debian.org/debian}

TMP="$ROOTFS.tmp"
rm -rf "$TMP"
mkdir -p "$(dirname "$ROOTFS")"
echo "debootstrap bookworm from $MIRROR ..."
debootstrap --variant=minbase --include="$PKGS" bookworm "$TMP" "$MIRROR" > "$ROOTFS.debootstrap.log" 2>&1 || {
    tail -n 20 "$ROOTFS.debootstrap.log"; exit 1; }

mkdir -p "$TMP/lib/modules"
cp -a "/usr/lib/uml/modules/$UMLVER" "$TMP/lib/modules/"
depmod -b "$TMP" "$UMLVER"

echo uml-ecu > "$TMP/etc/hostname"
printf 'hostfs / hostfs defaults 0 0\n' > "$TMP/etc/fstab"
cp /etc/resolv.conf "$TMP/etc/resolv.conf"
# pip inside the chroot must trust what the host trusts (a TLS-intercepting proxy's CA included).
for ca in /etc/ssl/certs/ca-certificates.crt ${PIP_CERT:-} ${REQUESTS_CA_BUNDLE:-} ${SSL_CERT_FILE:-}; do
    if [ -f "$ca" ]; then mkdir -p "$TMP$(dirname "$ca")"; cp "$ca" "$TMP$ca"; fi
done
# Quiet, fast boot: no gettys on a console nobody reads; networkd manages can0 (80-can.network).
chroot "$TMP" systemctl mask getty@tty1.service serial-getty@ttyS0.service console-getty.service \
    systemd-networkd-wait-online.service apt-daily.timer apt-daily-upgrade.timer e2scrub_all.timer \
    fstrim.timer > /dev/null 2>&1 || true
chroot "$TMP" systemctl enable systemd-networkd.service > /dev/null 2>&1

echo "venv + dependencies from PyPI: $DEPS"
mount --bind /proc "$TMP/proc"
trap 'umount "$TMP/proc" 2>/dev/null || true' EXIT
chroot "$TMP" python3 -m venv /opt/ecu-daemon/venv
# shellcheck disable=SC2086
chroot "$TMP" /opt/ecu-daemon/venv/bin/pip install -q --disable-pip-version-check $DEPS
umount "$TMP/proc"
trap - EXIT

rm -rf "$ROOTFS"
mv "$TMP" "$ROOTFS"
echo "$WANT" > "$ROOTFS/.ecu-rootfs-stamp"
du -sh "$ROOTFS"
