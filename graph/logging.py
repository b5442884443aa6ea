"""Node loggers with rclpy's interface and ROS 2's console format.

``node.get_logger().info("text")`` prints, on stderr, one line per message::

    [INFO] [1717000000.123456789] [scanner.phase]: text

(severity, wall-clock time in seconds with nanoseconds, logger name). A node's logger name is its
namespace and name joined by dots, as rclpy does (``/scanner/phase`` -> ``scanner.phase``). The
loggers sit on Python's :mod:`logging` under ``dptpu.node`` (not propagated to the root logger), so a
test can attach a handler to ``logging.getLogger("dptpu.node")``. Levels come from
``--ros-args --log-level LEVEL`` or ``--log-level NAME:=LEVEL`` or :func:`set_logger_level`.
"""

from __future__ import annotations

import logging as _logging
import sys
import threading
import time
from enum import IntEnum

__all__ = ["LoggingSeverity", "RcutilsLogger", "get_logger", "set_logger_level", "get_logger_level",
           "parse_severity", "ROOT_LOGGER_NAME"]

#: Python logger under which every node logger lives.
ROOT_LOGGER_NAME = "dptpu.node"


class LoggingSeverity(IntEnum):
    """rclpy's severities; the values equal Python's logging levels (WARN = WARNING)."""

    UNSET = 0
    DEBUG = 10
    INFO = 20
    WARN = 30
    ERROR = 40
    FATAL = 50


_NAMES = {"DEBUG": LoggingSeverity.DEBUG, "INFO": LoggingSeverity.INFO, "WARN": LoggingSeverity.WARN,
          "WARNING": LoggingSeverity.WARN, "ERROR": LoggingSeverity.ERROR, "FATAL": LoggingSeverity.FATAL,
          "UNSET": LoggingSeverity.UNSET}
_LABELS = {10: "DEBUG", 20: "INFO", 30: "WARN", 40: "ERROR", 50: "FATAL"}


def parse_severity(level) -> LoggingSeverity:
    """``"info"``, ``"WARN"``, ``20`` or a LoggingSeverity -> LoggingSeverity; else ValueError."""
    if isinstance(level, str):
        try:
            return _NAMES[level.strip().upper()]
        except KeyError:
            raise ValueError(f"log level must be one of debug, info, warn, error, fatal; got {level!r}") from None
    try:
        return LoggingSeverity(level)
    except ValueError:
        raise ValueError(f"log level must be one of {[int(s) for s in LoggingSeverity]}; got {level!r}") from None


class _RosFormatter(_logging.Formatter):
    def format(self, record):
        stamp_ns = getattr(record, "stamp_ns", None) or int(record.created * 1e9)
        seconds, nanoseconds = divmod(stamp_ns, 1_000_000_000)
        name = getattr(record, "ros_name", record.name)
        text = f"[{_LABELS.get(record.levelno, record.levelname)}] [{seconds}.{nanoseconds:09d}] [{name}]: " \
               f"{record.getMessage()}"
        if record.exc_info:
            text += "\n" + self.formatException(record.exc_info)
        return text


class _StderrHandler(_logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is at the time (so pytest's capture sees it)."""

    def __init__(self):
        super().__init__(sys.stderr)

    def emit(self, record):
        self.stream = sys.stderr
        super().emit(record)


_root = _logging.getLogger(ROOT_LOGGER_NAME)
_setup_lock = threading.Lock()


def _ensure_handler() -> None:
    with _setup_lock:
        if not any(isinstance(h, _StderrHandler) for h in _root.handlers):
            handler = _StderrHandler()
            handler.setFormatter(_RosFormatter())
            _root.addHandler(handler)
            _root.propagate = False
            if _root.level == _logging.NOTSET:
                _root.setLevel(_logging.INFO)


def _python_name(name: str) -> str:
    return f"{ROOT_LOGGER_NAME}.{name}" if name else ROOT_LOGGER_NAME


class RcutilsLogger:
    """A named logger: ``debug``, ``info``, ``warn``/``warning``, ``error``, ``fatal``.

    Each method takes the message and, like rclpy, the keyword options ``throttle_duration_sec``
    (log at most once per that many seconds from this call site), ``once`` (only the first time)
    and ``skip_first`` (not the first time). Returns True when the message was logged.
    """

    def __init__(self, name: str = ""):
        if not isinstance(name, str):
            raise ValueError(f"logger name must be a str; got {name!r}")
        self.name = name
        self._logger = _logging.getLogger(_python_name(name))
        self._sites: dict = {}
        self._sites_lock = threading.Lock()
        _ensure_handler()

    def get_child(self, name: str) -> RcutilsLogger:
        """The logger ``<this name>.<name>``."""
        if not name:
            raise ValueError("child logger name must not be empty")
        return RcutilsLogger(f"{self.name}.{name}" if self.name else name)

    def set_level(self, level) -> None:
        severity = parse_severity(level)
        self._logger.setLevel(int(severity))

    def get_effective_level(self) -> LoggingSeverity:
        return LoggingSeverity(self._logger.getEffectiveLevel())

    def is_enabled_for(self, severity) -> bool:
        return self._logger.isEnabledFor(int(parse_severity(severity)))

    def log(self, message, severity, *, throttle_duration_sec=None, once=False, skip_first=False,
            exc_info=None, _stacklevel: int = 2) -> bool:
        severity = parse_severity(severity)
        if not self._logger.isEnabledFor(int(severity)):
            return False
        if throttle_duration_sec is not None or once or skip_first:
            frame = sys._getframe(_stacklevel)
            if not self._site_allows((frame.f_code.co_filename, frame.f_lineno), throttle_duration_sec, once,
                                     skip_first):
                return False
        self._logger.log(int(severity), "%s", message, exc_info=exc_info,
                         extra={"ros_name": self.name or "root", "stamp_ns": time.time_ns()})
        return True

    def _site_allows(self, site, throttle_sec, once, skip_first) -> bool:
        now = time.monotonic()
        with self._sites_lock:
            calls, last = self._sites.get(site, (0, None))
            allowed = not (once and calls >= 1) and not (skip_first and calls == 0)
            if allowed and throttle_sec is not None and last is not None and now - last < throttle_sec:
                allowed = False
            self._sites[site] = (calls + 1, now if allowed else last)
            return allowed

    def debug(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.DEBUG, _stacklevel=3, **kwargs)

    def info(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.INFO, _stacklevel=3, **kwargs)

    def warning(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.WARN, _stacklevel=3, **kwargs)

    warn = warning

    def error(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.ERROR, _stacklevel=3, **kwargs)

    def fatal(self, message, **kwargs) -> bool:
        return self.log(message, LoggingSeverity.FATAL, _stacklevel=3, **kwargs)

    def __repr__(self):
        return f"RcutilsLogger({self.name!r})"


def get_logger(name: str) -> RcutilsLogger:
    """A logger named ``name`` (dots separate levels, e.g. ``"scanner.phase"``)."""
    return RcutilsLogger(name)


def set_logger_level(name: str, level) -> None:
    """Set the level of logger ``name`` (``""`` = the default for every node logger)."""
    _ensure_handler()
    _logging.getLogger(_python_name(name)).setLevel(int(parse_severity(level)))


def get_logger_level(name: str) -> LoggingSeverity:
    return LoggingSeverity(_logging.getLogger(_python_name(name)).getEffectiveLevel())
