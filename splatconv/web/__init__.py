"""The browser player: a WebGL2 page of our own, a leaf of the package.

The page (``assets/``: HTML, CSS, JavaScript, the depth-sort worker) runs the same
shader sources as :mod:`splatconv.render` (read from ``splatconv/render/shaders``,
never copied). :mod:`.page` builds it, self-contained, around one scene or a list
of segments, given as bytes or URLs. Nothing here reads or writes a scene file or
knows a format: publishing (:mod:`splatconv.publish`, which writes every ``.html``
page) and the ``view`` server (:mod:`splatconv.server`) use it.
Nothing here imports moderngl.
"""
