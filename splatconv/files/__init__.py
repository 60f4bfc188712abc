"""Files, a module per job: opening inputs, atomic output, the signals that end a run, paging mapped input.

* :mod:`~splatconv.files.inputs`: open a regular file for reading (devices, FIFOs refused).
* :mod:`~splatconv.files.output`: check an output path, write one file or a group of files atomically.
* :mod:`~splatconv.files.stale`: files locked while in use, so that those a killed run left are removed.
* :mod:`~splatconv.files.signals`: SIGTERM and SIGHUP end a run as Ctrl-C does; held for an instant.
* :mod:`~splatconv.files.paging`: map a file mapping's pages in one call.

Nothing here knows a format; :mod:`splatconv.zstd` builds ``.zst`` streams on these.
"""
