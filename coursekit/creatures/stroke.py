"""The stroke of a swim: its phase over time, and key frames that show one whole stroke.

Evolved swimmers beat fast: the champions' strokes last 0.3-0.5 s. Key frames spaced evenly over
a 10 s swim (the paper's Figure 3, :func:`~coursekit.creatures.render.keyframes`) then catch the
stroke at whatever phase their times fall on, often the same one twice, and the strip shows a body
that seems to glide. :func:`keyframe_picks` keeps the frames spread over the swim but moves each
one back by less than a stroke, to the next phase of the stroke: the panels after the first show
it at 0, 1/(n-1), 2/(n-1), ... of a cycle, while the trail shows the way travelled.

The phase is measured, not extrapolated from a period: :func:`stroke_phase` takes the main mode of
the joints' motion (their first principal component over the swim) and counts its beats, one turn
from one upward zero crossing to the next. A stroke that speeds up or drifts keeps its phase that
way; a period fitted once would be off by half a cycle after a dozen strokes. The analytic signal
(``scipy.signal.hilbert``) was tried instead and was less accurate at the ends of the swim, where
the last key frame is (``benchmarks/NOTES.md``).
"""

from __future__ import annotations

import numpy as np

#: A joint motion whose main mode has a smaller standard deviation (rad or m) has no stroke to show.
MIN_AMPLITUDE = 1e-3


def stroke_phase(trajectory: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, float] | None:
    """``(phase, period)``: the phase (rad, one per frame, growing) of the joints' main mode of
    motion and the stroke's mean period (s), or ``None`` when there is no stroke to show: no
    joints, fewer than 8 frames, a value that is not finite, a main mode under
    :data:`MIN_AMPLITUDE`, or fewer than 3 beats.

    A beat is an upward zero crossing of the main mode after it has been below ``-0.3`` of its
    standard deviation (so that a wiggle about zero is not a beat); the phase grows by one turn
    from beat to beat, linearly in time between them, and at the rate of the nearest stroke
    before the first beat and after the last.

    Args:
        trajectory: (F, nq) MuJoCo-layout ``qpos`` frames (root position, root quaternion, joints).
        times: (F,) increasing times of the frames (s).
    """
    q = np.asarray(trajectory, dtype=np.float64)[:, 7:]
    times = np.asarray(times, dtype=np.float64)
    if q.shape[1] == 0 or len(q) < 8 or not np.all(np.isfinite(q)):
        return None
    q = q - q.mean(axis=0)
    mode = q @ np.linalg.svd(q, full_matrices=False)[2][0]
    spread = float(np.std(mode))
    if not spread >= MIN_AMPLITUDE:
        return None
    beats, armed = [], False
    for i in range(1, len(mode)):
        armed |= bool(mode[i - 1] < -0.3 * spread)
        if armed and mode[i - 1] < 0 <= mode[i]:
            beats.append(times[i - 1] + (times[i] - times[i - 1]) * mode[i - 1] / (mode[i - 1] - mode[i]))
            armed = False
    if len(beats) < 3:
        return None
    beats = np.asarray(beats)
    turns = np.interp(times, beats, np.arange(len(beats), dtype=np.float64))
    before, after = times < beats[0], times > beats[-1]
    turns[before] = (times[before] - beats[0]) / (beats[1] - beats[0])
    turns[after] = len(beats) - 1 + (times[after] - beats[-1]) / (beats[-1] - beats[-2])
    return 2 * np.pi * turns, float((beats[-1] - beats[0]) / (len(beats) - 1))


def keyframe_picks(times: np.ndarray, n: int, stroke: tuple[np.ndarray, float] | None = None) -> np.ndarray:
    """Indices of ``n`` key frames among frames at ``times``, increasing.

    Evenly spaced from the first frame to the last; with a ``stroke`` (:func:`stroke_phase`) whose
    period fits between two of those, the second frame stays and each later frame ``k`` moves
    back, by less than one turn of the stroke's phase, to the frame whose phase is closest to
    ``(k - 1) / (n - 1)`` of a turn after the second frame's.
    """
    F = len(times)
    even = np.round(np.linspace(0, F - 1, n)).astype(int)
    if stroke is None or n < 3:
        return even
    phase, period = stroke
    spacing = float(times[even[2]] - times[even[1]])
    if not (period <= spacing and period >= 2 * float(np.median(np.diff(times)))):
        return even
    picks = [int(even[0]), int(even[1])]
    for k in range(2, n):
        frames = np.arange(picks[-1] + 1, even[k] + 1)
        window = frames[phase[frames] > phase[even[k]] - 2 * np.pi]
        target = phase[picks[1]] + 2 * np.pi * (k - 1) / (n - 1)
        off = np.angle(np.exp(1j * (phase[window] - target)))  # wrapped to (-pi, pi]
        picks.append(int(window[np.argmin(np.abs(off))]))
    return np.asarray(picks)
