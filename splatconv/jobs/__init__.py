"""The commands' work on files, a function per command; the CLI calls one and echoes what it returns.

Every job takes the same steps, written once in :mod:`~splatconv.jobs._steps`:
check the inputs' formats, the output's format and options and the output path
(before any reading: fail fast, touch nothing), read, refuse an empty scene the
output cannot hold, operate (:mod:`splatconv.ops`), write atomically
(:mod:`splatconv.io`). Each job tells its notes (lossy or noteworthy steps, in
words) to ``tell(lines)`` in the order and at the moment the command shows them,
and returns what it did.

* :mod:`~splatconv.jobs.convert`: ``convert`` of one scene file (:func:`splatconv.convert`).
* :mod:`~splatconv.jobs.frames`: ``convert`` of a frame sequence into one 4D scene.
* :mod:`~splatconv.jobs.bake`: ``bake`` (one moment, or a folder of moments).
* :mod:`~splatconv.jobs.merge`: ``merge`` (scenes on one timeline).
* :mod:`~splatconv.jobs.segments`: ``merge --segments`` (segments end to end), and its findings.

A module each, so that a command loads only the operations it runs.
"""
