"""The imperative shell of the live daemon: everything that touches a clock, a socket or a tty.

``can_bus``   python-can bus, asyncio reception, kernel time -> monotonic, error frames, bus-off TX gate
``serial_port``  GNSS tty read in a thread, receive timestamps at read, unplug / reconnect
``tick``      the 6 ms thread on absolute deadlines, lateness statistics
``health``    the Diagnostics snapshot assembled from all the parts (the host's part, then on the step grid)
``recorder``  ``--record DIR``: what was received, published and sent, and the tick record that replays it
``player``    the one real-time player: CAN frames and GNSS bytes on absolute deadlines (tools, demo)
``state_store``  atomic persistence of the learned quantities
``notify``    systemd READY / WATCHDOG / STATUS / STOPPING
``logging_setup``  journald-friendly stderr logging for every command, the one rate limiter
``output_file``  outputs checked against inputs, written aside, renamed into place (replay)
"""
