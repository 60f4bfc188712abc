"""The one place an OpenGL context is made."""

from __future__ import annotations

from ..errors import SplatconvError

#: What to tell a user whose machine has no usable OpenGL.
INSTALL_HINT = ("install an EGL driver: on Debian or Ubuntu the packages libegl1 and libgl1-mesa-dri "
                "(Mesa's llvmpipe renders on the CPU, no GPU or display needed)")


class RenderUnavailable(SplatconvError):
    """No OpenGL 3.3+ context can be made on this machine."""


def create_context():
    """A standalone (headless) moderngl context on EGL.

    Raises
    ------
    RenderUnavailable
        With what to install when moderngl, EGL or a GL 3.3 driver is missing.
    """
    try:
        import moderngl
    except ImportError as e:  # pragma: no cover - a dependency of the package
        raise RenderUnavailable(f"cannot import moderngl ({e}); pip install moderngl") from None
    try:
        ctx = moderngl.create_context(standalone=True, backend="egl")
    except Exception as e:
        raise RenderUnavailable(f"no OpenGL context ({str(e).strip() or type(e).__name__}); {INSTALL_HINT}") from None
    if ctx.version_code < 330:
        version = ctx.info.get("GL_VERSION", "?")
        ctx.release()
        raise RenderUnavailable(f"OpenGL {version} is too old (3.3 needed); {INSTALL_HINT}")
    return ctx
