"""The one headless matplotlib set-up of every figure nbvkit draws (plots, coverage.png, the
symmetry figure): bare Figures saved by their own Agg canvas, no pyplot."""
from __future__ import annotations


def _plt():
    """What the figure functions use of pyplot (subplots, close, get_cmap, Line2D), without
    pyplot's global figure registry and backend: each figure is a bare
    ``matplotlib.figure.Figure`` saved by its own Agg canvas, so two missions writing their
    figures in two threads of one process share no state (pyplot is not thread-safe), and
    nothing depends on the session's backend."""
    return _Figures


class _Figures:
    _FIGURE_KEYS = ("figsize", "dpi", "constrained_layout", "layout", "facecolor")

    @staticmethod
    def subplots(*args, **kw):
        from matplotlib.figure import Figure

        fig = Figure(**{k: kw.pop(k) for k in _Figures._FIGURE_KEYS if k in kw})
        return fig, fig.subplots(*args, **kw)

    @staticmethod
    def close(fig) -> None:
        """Nothing to do: the figure is not registered anywhere; dropping it frees it."""

    @staticmethod
    def get_cmap(name):
        import matplotlib

        return matplotlib.colormaps[name]

    @staticmethod
    def Line2D(*args, **kw):  # noqa: N802 - pyplot's name
        from matplotlib.lines import Line2D

        return Line2D(*args, **kw)
