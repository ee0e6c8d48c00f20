"""Fig. 2: the interaction graph (k = 3) of 5 robots on a 10 x 10 grid and its factor graph.

The paper's example has 5 robots whose swarm energy is a sum of 4 maximal-clique
energies (eps(x) = sum_{i=1}^{4} E_i(x_i)); its positions are not given, so
``experiments/example5.toml`` is a placement of ours with the same structure (k = 3,
4 maximal cliques). Fig. 3 uses the same robots.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mrfswarm import plots
from mrfswarm.discrete.interaction_graph import CliqueWeights, interaction_graph
from mrfswarm.figures.runs import experiment_config
from mrfswarm.scenario import Scenario, build_scenario

#: The experiment config of the 5-robot example (Figs. 2 and 3a/b).
EXAMPLE = "example5"


def example_scenario() -> Scenario:
    """The 5 robots of ``experiments/example5.toml`` on their 10 x 10 grid."""
    return build_scenario(experiment_config(EXAMPLE))


@dataclass(frozen=True)
class ExampleGraph:
    """The numbers behind Fig. 2.

    Attributes
    ----------
    positions
        (5, 2) robot cells.
    k
        Neighbours per robot.
    graph
        Edges, maximal cliques and their pairwise reduction.
    """

    positions: np.ndarray
    k: int
    graph: CliqueWeights

    @property
    def degrees(self) -> np.ndarray:
        """Neighbours of each robot in the symmetric k-NN graph."""
        return np.bincount(self.graph.edges.ravel(), minlength=len(self.positions))


def example_graph() -> ExampleGraph:
    """The k-NN interaction graph of the example's robots and its maximal cliques."""
    scn = example_scenario()
    k = scn.config.interaction.k
    return ExampleGraph(positions=scn.start, k=k, graph=interaction_graph(scn.start, k))


def draw_grid_robots(ax, g: ExampleGraph, edges: bool = True, n: int = 10) -> None:
    """The robots (numbered) on the example's n x n grid, with the graph's edges."""
    ax.set_xticks(np.arange(-0.5, n, 1), minor=True)
    ax.set_yticks(np.arange(-0.5, n, 1), minor=True)
    ax.grid(which="minor", color="0.85", lw=0.8)
    ax.tick_params(which="minor", length=0)
    ax.set_xticks(range(0, n, 2))
    ax.set_yticks(range(0, n, 2))
    plots.draw_graph(ax, g.positions, g.graph.edges if edges else np.zeros((0, 2), int))
    ax.set_xlim(-0.5, n - 0.5)
    ax.set_ylim(-0.5, n - 0.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def _crossings(var_slot: dict[int, int], fac_slot: list[int], cliques: list[np.ndarray]) -> int:
    """Edge crossings of a two-row bipartite drawing with the given slots."""
    segs = [(var_slot[int(i)], fac_slot[j]) for j, c in enumerate(cliques) for i in c]
    return sum((a0 - a1) * (b0 - b1) < 0 for k, (a0, b0) in enumerate(segs) for a1, b1 in segs[k + 1:])


def factor_graph_layout(n: int, cliques: list[np.ndarray]) -> tuple[list[int], list[int]]:
    """Slots of variables and factors in the two rows with the fewest edge crossings.

    Exhaustive over both orders for small examples (the paper's has 5 variables and 4
    factors); index order otherwise.
    """
    import itertools
    import math

    if math.factorial(n) * math.factorial(len(cliques)) > 50_000:
        return list(range(n)), list(range(len(cliques)))
    best = None
    for vp in itertools.permutations(range(n)):
        var_slot = {v: s for s, v in enumerate(vp)}
        for fp in itertools.permutations(range(len(cliques))):
            c = _crossings(var_slot, list(fp), cliques)
            if best is None or c < best[0]:
                best = (c, [var_slot[i] for i in range(n)], list(fp))
    assert best is not None  # at least one permutation
    return best[1], best[2]


def draw_factor_graph(ax, g: ExampleGraph) -> None:
    """Variable nodes x_i (circles, top) joined to the maximal-clique factors c_j (squares, bottom)."""
    n = len(g.positions)
    cliques = g.graph.cliques
    var_slot, fac_slot = factor_graph_layout(n, cliques)
    xv = np.asarray(var_slot, dtype=float)
    xf = (np.linspace(0, n - 1, len(cliques)) if len(cliques) > 1 else np.array([(n - 1) / 2]))[fac_slot]
    yv, yf = 1.0, 0.0
    for j, c in enumerate(cliques):
        for i in c:
            ax.plot([xv[i], xf[j]], [yv, yf], "-", color="0.4", lw=1.3, zorder=1)
    ax.scatter(xv, np.full(n, yv), s=700, c="tab:blue", edgecolors="k", zorder=3)
    for i in range(n):
        ax.text(xv[i], yv, f"$x_{i + 1}$", ha="center", va="center", color="white", fontsize=11, zorder=4)
    ax.scatter(xf, np.full(len(cliques), yf), s=620, marker="s", c="tab:orange", edgecolors="k", zorder=3)
    for j, c in enumerate(cliques):
        ax.text(xf[j], yf, f"$c_{j + 1}$", ha="center", va="center", fontsize=11, zorder=4)
        members = ",".join(str(i + 1) for i in c)
        ax.text(xf[j], yf - 0.2, f"{{{members}}}", ha="center", va="top", fontsize=9, color="0.25")
    ax.text(-0.55, yv, "robots", ha="right", va="center", fontsize=9.5, color="0.3")
    ax.text(-0.55, yf, "cliques", ha="right", va="center", fontsize=9.5, color="0.3")
    ax.set_xlim(-1.7, n - 0.5)
    ax.set_ylim(-0.55, 1.3)
    ax.axis("off")


def make_fig2(out: Path, quick: bool = False) -> list[Path]:
    """Write ``fig2_interaction_graph.png``."""
    g = example_graph()
    plt = plots._plt()
    with plots.paper_style():
        fig, axes = plt.subplots(1, 2, figsize=(10, 4.6), gridspec_kw={"width_ratios": [1, 1.25]},
                                 layout="constrained")
        draw_grid_robots(axes[0], g)
        plots.panel_title(axes[0], "a", f"interaction graph, k = {g.k} ({len(g.graph.edges)} edges)")
        draw_factor_graph(axes[1], g)
        plots.panel_title(axes[1], "b", f"factor graph: {len(g.graph.cliques)} maximal cliques")
        fig.suptitle(r"Fig. 2: 5 robots on a 10 x 10 grid; swarm energy "
                     r"$\varepsilon(\mathbf{x}) = \Sigma_c\, E_c(\mathbf{x}_c)$"
                     " over the maximal cliques c of the k-NN graph")
        return [plots.save_figure(fig, Path(out) / "fig2_interaction_graph.png")]


def numbers_fig2(quick: bool = False) -> dict:
    """Edges, degrees and maximal cliques of the example (1-based robot numbers)."""
    g = example_graph()
    return {
        "robots": g.positions.tolist(),
        "k": g.k,
        "edges": (g.graph.edges + 1).tolist(),
        "degrees": g.degrees.tolist(),
        "maximal_cliques": [(c + 1).tolist() for c in g.graph.cliques],
    }
