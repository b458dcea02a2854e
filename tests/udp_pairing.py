"""The pairing key the UDP tests share (frame format 3: only a host with the device's key arms it),
and the files a command line run needs: the key file (mode 600) and a description naming it."""

from __future__ import annotations

import os
from pathlib import Path

#: the pairing key of every emulator and host in the tests
KEY = bytes(range(32))
#: another key: a host holding it is an intruder
WRONG_KEY = bytes(range(1, 33))


def key_file(folder: Path, key: bytes = KEY, name: str = "display.key") -> Path:
    """Write ``key`` to ``folder / name`` readable by its owner only, and return the path."""
    path = Path(folder) / name
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    try:
        os.write(descriptor, key)
    finally:
        os.close(descriptor)
    os.chmod(path, 0o600)
    return path


def paired_description(folder: Path, description, name: str = "display.json") -> Path:
    """Save ``description`` to ``folder / name`` naming a key file next to it (``display.key``)."""
    key_file(folder)
    return description.replace(pairing_key_file="display.key").save(Path(folder) / name)


def emulator_thread(**kwargs):
    """The emulator in a thread on a free loopback port with :data:`KEY` (keywords go to ``emulate``);
    returns ``(port, finish, logs)``: ``finish()`` stops it and returns its summary."""
    import threading
    import time

    from tactilab.experiments.devices.emulator import emulate

    stop, logs, result = threading.Event(), [], {}
    options = {"port": 0, "max_seconds": 120, "log": logs.append, "stop": stop, "handle_signals": False,
               "pairing_key": KEY, **kwargs}
    thread = threading.Thread(target=lambda: result.update(summary=emulate(**options)), daemon=True)
    thread.start()
    while not logs:
        assert thread.is_alive(), "the emulator ended before listening"
        time.sleep(0.005)

    def finish():
        stop.set()
        thread.join(timeout=10)
        return result.get("summary")

    return int(logs[0].split(":")[2].split()[0]), finish, logs
