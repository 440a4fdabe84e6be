"""History of a run: fitness statistics and diversity per generation (the fitness curve of the
paper's introduction: evolution as iterative improvement of a population).

A :class:`History` is plain data -- lists of numbers -- so it compares with ``==``, converts to
dicts and JSON, and survives checkpoints. ``History.plot`` draws the classic GA plot: best,
mean and median fitness with a +-1 standard deviation band, and diversity on a second axis.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, fields
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    import matplotlib.axes

__all__ = ["History"]

FORMAT = "coursekit.ga.history/1"


@dataclass
class History:
    """Per-generation statistics. Entry ``i`` of every list belongs to ``generation[i]``.

    Attributes:
        generation: generation numbers (0 is the evaluated initial population).
        best, mean, median, std: fitness statistics of the whole population.
        diversity: the run's diversity figure (default: fraction of distinct genomes).
        evaluations: fitness evaluations spent on that generation (elites are not re-evaluated).
    """

    generation: list = field(default_factory=list)
    best: list = field(default_factory=list)
    mean: list = field(default_factory=list)
    median: list = field(default_factory=list)
    std: list = field(default_factory=list)
    diversity: list = field(default_factory=list)
    evaluations: list = field(default_factory=list)

    def record(self, generation: int, fitness: ArrayLike, diversity: float, evaluations: int) -> None:
        """Append the statistics of one generation.

        Args:
            generation: generation number.
            fitness: 1-D array of the population's fitness.
            diversity: diversity figure of the population.
            evaluations: number of fitness evaluations spent on this generation.
        """
        f = np.asarray(fitness, dtype=np.float64)
        self.generation.append(int(generation))
        self.best.append(float(f.max()))
        self.mean.append(float(f.mean()))
        self.median.append(float(np.median(f)))
        self.std.append(float(f.std()))
        self.diversity.append(float(diversity))
        self.evaluations.append(int(evaluations))

    def copy(self) -> "History":
        """An independent copy (later records to either do not show in the other)."""
        return History(**{f.name: list(getattr(self, f.name)) for f in fields(self)})

    def __len__(self) -> int:
        return len(self.generation)

    def to_dict(self) -> dict:
        """Plain dict with a ``format`` field (JSON-ready)."""
        return {"format": FORMAT, **asdict(self)}

    @classmethod
    def from_dict(cls, data: dict) -> "History":
        """Inverse of :meth:`to_dict`; refuses foreign or inconsistent data with a ValueError."""
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            got = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise ValueError(f"format: expected {FORMAT!r}, got {got!r}")
        names = [f.name for f in fields(cls)]
        missing = [n for n in names if n not in data]
        if missing:
            raise ValueError(f"History: missing fields {missing}")
        lengths = {n: len(data[n]) for n in names}
        if len(set(lengths.values())) != 1:
            raise ValueError(f"History: all fields must have the same length, got {lengths}")
        return cls(
            **{n: [int(v) for v in data[n]] if n in ("generation", "evaluations") else [float(v) for v in data[n]] for n in names}
        )

    def to_json(self) -> str:
        return json.dumps(self.to_dict())

    @classmethod
    def from_json(cls, text: str) -> "History":
        return cls.from_dict(json.loads(text))

    def __repr__(self) -> str:
        """Short: how long the run is and its best (the lists are in the fields).

        >>> h = History(); h.record(0, [1.0, 3.0], 1.0, 2); h.record(1, [2.0, 4.0], 0.5, 2); h
        History(2 generations, best 4 in generation 1)
        """
        if not self.generation:
            return "History(no generations)"
        k = int(np.argmax(self.best))
        n = len(self.generation)
        return f"History({n} generation{'s' * (n != 1)}, best {self.best[k]:.4g} in generation {self.generation[k]})"

    def _repr_png_(self) -> bytes | None:
        """The plot of :meth:`plot`, so a notebook shows a history as its fitness curve."""
        if not self.generation:
            return None
        import io

        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(6, 3.5), dpi=100)  # not pyplot: the figure is not also shown by the inline backend
        FigureCanvasAgg(fig)
        self.plot(ax=fig.add_subplot())
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png")
        return buf.getvalue()

    def plot(self, ax: matplotlib.axes.Axes | None = None, *, label: str | None = None,
             diversity: bool = True) -> matplotlib.axes.Axes:
        """Plot best / mean / median fitness (mean +- std shaded) and diversity per generation.

        Args:
            ax: matplotlib Axes to draw on (default: a new figure).
            label: prefix for the legend entries (handy when overlaying runs).
            diversity: also draw diversity (dotted, on a twin axis at the right).
        Returns:
            the fitness Axes.
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(7, 4))
        g = np.asarray(self.generation)
        prefix = f"{label}: " if label else ""
        (line,) = ax.plot(g, self.best, lw=2, label=f"{prefix}best")
        color = line.get_color()
        ax.plot(g, self.mean, color=color, lw=1, ls="--", label=f"{prefix}mean")
        ax.plot(g, self.median, color=color, lw=1, ls=":", label=f"{prefix}median")
        mean, std = np.asarray(self.mean), np.asarray(self.std)
        ax.fill_between(g, mean - std, mean + std, color=color, alpha=0.15, lw=0)
        ax.set_xlabel("generation")
        ax.set_ylabel("fitness")
        handles, labels = ax.get_legend_handles_labels()
        if diversity:
            twin = ax.twinx()
            (d,) = twin.plot(g, self.diversity, color=color, lw=1, alpha=0.6, ls=(0, (1, 3)), label=f"{prefix}diversity")
            twin.set_ylabel("diversity")
            twin.set_ylim(0, max(1.0, max(self.diversity, default=1.0)) * 1.05)
            handles.append(d)
            labels.append(d.get_label())
        ax.legend(handles, labels, loc="lower right", fontsize="small")
        return ax
