"""The browser player: a WebGL2 page of our own and the ``view`` server.

The page (``assets/``: HTML, CSS, JavaScript, the depth-sort worker) runs the same
shader sources as :mod:`splatconv.render` (read from ``splatconv/render/shaders``,
never copied). :mod:`.page` builds it, self-contained, around one scene or a list
of segments; :mod:`.server` serves it on 127.0.0.1 for ``splatconv view``.
Nothing here imports moderngl.
"""
