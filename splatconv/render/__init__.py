"""Headless preview rendering with splaTV's own shader maths (moderngl, EGL).

Importing :mod:`splatconv` never imports this package; it imports moderngl only
when a context is made (:mod:`splatconv.render.gl`).
"""
