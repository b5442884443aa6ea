"""Tools built on the runtime (:mod:`dptpu.graph`): launch files, MCAP recording and playback, introspection."""
