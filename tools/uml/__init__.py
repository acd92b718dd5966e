"""User-mode Linux: a real kernel CAN stack (vcan, slcan) and a real systemd on machines whose kernel has neither.

``boot.py`` finds/installs the UML kernel and boots it with bounded timeouts; ``guest_init.sh`` is
PID 1 for the share-the-host's-files guest; ``guest_replay.py`` runs a replay scenario inside it;
``build_rootfs.sh`` + ``systemd_probe.sh`` + ``slcan_adapter.py`` make and drive the systemd guest.
See DEVELOPERS.md, "Kernel tests (user-mode Linux)".
"""
