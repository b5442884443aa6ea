"""CurveZMQ keys of a user's graph, generated into its discovery folder when tcp is used without configured keys.

With ``DPTPU_TRANSPORT=tcp`` (or peers) every endpoint is a tcp port that any local user, or any host that can
reach the interface, may connect to. Without CurveZMQ such a stranger reads every message, publishes on any
topic and calls any service (issue 19: another local user read clouds, started scans and changed a node's
parameter). So tcp is CurveZMQ by default: when ``DPTPU_CURVE_SECRET_KEY`` is not set, every process of the user
uses one key pair kept in the discovery folder (mode 0700, so only the user can read it)::

    <domain folder>/curve/participant.key_secret   (mode 0600: public and secret key)
    <domain folder>/curve/participant.key          (mode 0600: public key)
    <domain folder>/curve/authorized/participant.key  (the keys allowed to connect: this pair's public key)

The first process that needs the keys creates them in a temporary folder and renames it into place (atomic:
two processes starting together end up with the same keys). Other hosts of a peer exchange need the same pair
(copy the ``curve`` folder) or their own keys configured with ``DPTPU_CURVE_SECRET_KEY`` and
``DPTPU_CURVE_AUTHORIZED_KEYS`` (docs/reliability.md). ``DPTPU_CURVE=off`` turns Curve off for tcp, with a warning.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

__all__ = ["CURVE_FOLDER", "ensure_domain_keys"]

#: Name of the key folder inside the domain's discovery folder.
CURVE_FOLDER = "curve"
_NAME = "participant"


def ensure_domain_keys(domain_directory: Path) -> tuple[Path, Path]:
    """``(secret certificate file, authorized keys folder)`` of the user's graph in ``domain_directory``, made when
    absent (see the module docstring).

    Raises
    ------
    PermissionError
        When the key folder or its secret file can be read by other users.
    """
    import zmq.auth  # deferred: only with tcp; zmq.auth brings asyncio in

    folder = Path(domain_directory) / CURVE_FOLDER
    if not folder.is_dir():
        staging = Path(tempfile.mkdtemp(prefix=".curve-", dir=domain_directory))  # mode 0700
        try:
            public_file, secret_file = zmq.auth.create_certificates(str(staging), _NAME)
            os.chmod(public_file, 0o600)
            os.chmod(secret_file, 0o600)
            authorized = staging / "authorized"
            authorized.mkdir(mode=0o700)
            shutil.copy(public_file, authorized / Path(public_file).name)
            try:
                os.rename(staging, folder)
            except OSError:  # another process was first: use its keys
                pass
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    secret = folder / f"{_NAME}.key_secret"
    for path in (folder, secret):
        if path.stat().st_mode & 0o077:
            raise PermissionError(f"CurveZMQ key {str(path)!r} is readable by other users (mode "
                                  f"{oct(path.stat().st_mode & 0o777)}); chmod go-rwx it")
    return secret, folder / "authorized"
