"""Headless preview rendering with splaTV's own shader maths (moderngl, EGL).

Importing :mod:`splatconv` never imports this package; it imports moderngl only
when a context is made (:mod:`splatconv.render.gl`).

The layers, from the GL up:

* :mod:`~splatconv.render.gl` makes the one OpenGL context; ``shaders/`` hold the
  viewer's GLSL; :mod:`~splatconv.render.camera` and :mod:`~splatconv.render.sort`
  are the viewer's camera maths and depth order.
* :mod:`~splatconv.render.layout` declares the float reference texture
  (``FLOAT_TEXELS``) and builds it from :func:`splatconv.viewer.float_record`.
* :mod:`~splatconv.render.preview`: :class:`~splatconv.render.preview.Renderer`
  draws a ``.splatv`` texture or float reference rows from a
  :class:`~splatconv.render.preview.View`.
* :mod:`~splatconv.render.frames`: load a scene file once, pick the cameras,
  draw frames (:func:`~splatconv.render.frames.render_frames`,
  :func:`~splatconv.render.frames.render_scene` for an in-memory scene) and
  compare two scenes frame by frame (:func:`~splatconv.render.frames.compare_frames`).
* :mod:`~splatconv.render.verify` (``verify``, ``diff`` of scene files) and
  :mod:`~splatconv.render.commands` (``render``, ``diff`` of files) return data;
  :mod:`~splatconv.render.diff` measures two images (PSNR, errors, heatmap);
  :mod:`~splatconv.render.images` writes frames. Text is :mod:`splatconv.text`'s.
"""
