"""Run ``dptpu ARGV`` in a child process whose stderr is a real pseudo-terminal (where tqdm draws its bars)."""
from __future__ import annotations

import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios
from pathlib import Path


def run_on_a_terminal(argv, cwd: Path) -> tuple[int, str, str]:
    """``dptpu ARGV`` with its stderr on a pseudo-terminal of 160 columns and its stdout in a file (not a terminal).

    Returns
    -------
    (exit code, stdout, what the terminal received)
    """
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 160, 0, 0))  # 160 columns, as a terminal has
    stdout_path = Path(cwd) / f"stdout-{os.getpid()}-{id(argv)}.txt"
    try:
        with stdout_path.open("wb") as stdout:
            proc = subprocess.Popen([sys.executable, "-c",
                                     "import sys; from dptpu.cli.main import main; sys.exit(main())", *map(str, argv)],
                                    cwd=cwd, stdout=stdout, stderr=slave)
            os.close(slave)
            slave = -1
            received = b""
            while True:
                try:
                    chunk = os.read(master, 4096)
                except OSError:  # EIO: the child closed the terminal
                    break
                if not chunk:
                    break
                received += chunk
            code = proc.wait(timeout=120)
        return code, stdout_path.read_text(), received.decode(errors="replace")
    finally:
        os.close(master)
        if slave != -1:
            os.close(slave)
        stdout_path.unlink(missing_ok=True)
