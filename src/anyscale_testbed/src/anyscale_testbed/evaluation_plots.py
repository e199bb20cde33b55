"""The evaluation's figures as PNGs (matplotlib, Agg backend, no display): Fig. 5, each test's
path coloured by configuration in the paper's four colours over the map with the WiFi coverage
underneath, and Fig. 6, each run's time to complete as bars with its mean |omega| on the right
axis. The figures are drawn from what evaluation_figures reads out of the records."""
import math
from typing import Optional, Sequence, Tuple

import numpy as np

from anyscale_nav_demo.results import (CONFIGURATION_COLOURS, CONFIGURATIONS,
                                       configuration_runs)

from .link_shaper import FULL_SCALE_MBPS, CoverageGrid
from .testbed_record import LINK_AHEAD_RETURN, LINK_LOSS_RETURN, OTHER_RETURN

# How Fig. 5 marks the returns where they were decided: after a link loss, planned before a
# hole the link map foresaw, other planned ones.
RETURN_MARKERS = {LINK_LOSS_RETURN: dict(marker="X", color="black", s=70),
                  LINK_AHEAD_RETURN: dict(marker="^", color="#f0a30a", edgecolors="black", s=60),
                  OTHER_RETURN: dict(marker="o", color="white", edgecolors="black", s=30)}


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def map_image(occupied: np.ndarray, unknown: np.ndarray) -> np.ndarray:
    """Grey levels of a map for imshow: walls black, unknown light grey, free white."""
    return np.where(occupied, 0.0, np.where(unknown, 0.75, 1.0))


def draw_fig5(png_path: str, occupied: np.ndarray, unknown: np.ndarray, resolution: float,
              origin_xy: Tuple[float, float],
              tests: Sequence[Tuple[str, np.ndarray, Sequence[str]]],
              coverage: Optional[CoverageGrid] = None):
    """One panel per test: (title, (N, 2) path, configuration per point[, returns]), returns
    (x, y, kind) marked where each was decided (RETURN_MARKERS)."""
    plt = _pyplot()
    from matplotlib.lines import Line2D
    panels = max(1, len(tests))
    cols = min(panels, 2)
    rows = int(math.ceil(panels / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(5.5 * cols, 5.5 * rows), dpi=100,
                             squeeze=False)
    h, w = occupied.shape
    extent = (origin_xy[0], origin_xy[0] + w * resolution,
              origin_xy[1], origin_xy[1] + h * resolution)
    for k, ax in enumerate(axes.ravel()):
        if k >= len(tests):
            ax.axis("off")
            continue
        title, xy, configurations = tests[k][:3]
        returns = tests[k][3] if len(tests[k]) > 3 else ()
        ax.imshow(map_image(occupied, unknown), cmap="gray", origin="lower", vmin=0, vmax=1,
                  extent=extent)
        if coverage is not None:
            ch, cw = coverage.mbps.shape
            cx, cy = coverage.origin_xy
            shown = np.ma.masked_where(coverage.mbps <= 0, coverage.mbps)
            # Purple, apart from the configurations' colours; the lowest rate still shows.
            ax.imshow(shown, cmap="Purples", origin="lower", vmin=-0.3 * FULL_SCALE_MBPS,
                      vmax=FULL_SCALE_MBPS, alpha=0.5,
                      extent=(cx, cx + cw * coverage.resolution,
                              cy, cy + ch * coverage.resolution))
        for configuration, points in configuration_runs(xy, configurations):
            ax.plot(points[:, 0], points[:, 1], "-", lw=2.5,
                    color=CONFIGURATION_COLOURS[configuration])
        for kind, style in RETURN_MARKERS.items():
            at = [(x, y) for x, y, k in returns if k == kind]
            if at:
                ax.scatter(*zip(*at), zorder=5, linewidths=0.8, **style)
        ax.set_title(title)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
    handles = [Line2D([], [], color=CONFIGURATION_COLOURS[c], lw=3, label=c)
               for c in CONFIGURATIONS]
    shown = {k for t in tests if len(t) > 3 for _, _, k in t[3]}
    for kind, style in RETURN_MARKERS.items():
        if kind in shown:
            handles.append(Line2D([], [], ls="", marker=style["marker"],
                                  markerfacecolor=style["color"], markeredgecolor="black",
                                  markersize=8, label=kind))
    if coverage is not None:
        handles.append(Line2D([], [], color="#8c6bb1", lw=8, alpha=0.6,
                              label="WiFi coverage (model; darker = faster)"))
    fig.legend(handles=handles, loc="lower center", ncol=2 if cols == 1 else 3, fontsize=8)
    fig.suptitle("Fig. 5: path by configuration")
    fig.tight_layout(rect=(0, 0.12 if rows == 1 else 0.07, 1, 0.96))
    fig.savefig(png_path)
    plt.close(fig)


def draw_fig6(png_path: str, bars: Sequence[Tuple[str, float, float]]):
    """(name, time to complete s, mean |omega| deg/s) per run; NaN draws no bar / no point."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(max(6.0, 1.1 * len(bars) + 2), 4.5), dpi=100)
    names = [b[0] for b in bars]
    x = np.arange(len(bars))
    times = np.array([b[1] for b in bars], dtype=float)
    ax.bar(x, np.nan_to_num(times, nan=0.0), color="#4a78c2", label="time to complete")
    for i, t in enumerate(times):
        ax.text(i, 0 if math.isnan(t) else t, "not done" if math.isnan(t) else f"{t:.0f} s",
                ha="center", va="bottom", fontsize=8)
    ax.set_ylabel("time to complete (s)")
    ax.set_xticks(x)
    ax.set_xticklabels(names, rotation=30, ha="right", fontsize=8)
    right = ax.twinx()
    right.plot(x, [b[2] for b in bars], "o-", color="#d9531a", label="mean |ω|")
    right.set_ylabel("mean |ω| (°/s)")
    # Head room above the bars and the line for the legend.
    finite_times = times[np.isfinite(times)]
    if finite_times.size:
        ax.set_ylim(0, 1.3 * finite_times.max())
    omegas = np.array([b[2] for b in bars], dtype=float)
    finite_omegas = omegas[np.isfinite(omegas)]
    right.set_ylim(0, 1.4 * finite_omegas.max() if finite_omegas.size else 1.0)
    lines = ax.get_legend_handles_labels()
    more = right.get_legend_handles_labels()
    ax.legend(lines[0] + more[0], lines[1] + more[1], loc="upper right", fontsize=8)
    ax.set_title("Fig. 6: time to complete and mean angular velocity")
    fig.tight_layout()
    fig.savefig(png_path)
    plt.close(fig)
