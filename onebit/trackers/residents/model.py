"""The residents tracker's model: costs of attributing a motion event to a person.

A home's motion log is a sequence of events ``e_i = (t_i, s_i)``: the time of a sensor's
``ON`` edge and the sensor's node. Each person is a *track*: the chain of events they caused.
Attributing the events is choosing, for every event ``i``, its predecessor ``pred(i)`` -- the
previous event of the same person -- or a *birth* (``pred(i) = none``: the first event of a
person). The decoder (:mod:`onebit.trackers.residents.decode`) minimises

::

    J = sum_{i: pred(i) = none} b(i) + sum_{i: pred(i) = j} c(j, i) [+ sum_{i > 1} f(i)]
        with at most K births                                                          (1)

where ``c`` is the negative log-likelihood of a person's next event given their last one
(the *dwell-aware motion model*) and ``b`` the cost of a new person (penalised births: the
number of people is what (1) chooses, never more than ``K``).

Motion (eq. 2-3). A person whose last event was at node ``s_j`` at ``t_j`` next fires a sensor
at graph distance ``d = d(s_j, s_i)`` (metres) after ``dt = t_i - t_j``. People walk, and they
also sit for minutes without firing and then fire close to where they sat, so the spread of
the next sensor grows with the silence at walking speed ``v`` from a sensor footprint
``l0`` and saturates at ``l_max`` (a room's size)::

    l(dt) = min(l0 + v * dt, l_max)                                                   (2)
    c(j, i) = d(s_j, s_i) / l + ln Z_l(s_j) + w * ln(1 + dt / tau),
    Z_l(s_j) = sum_s exp(-d(s_j, s) / l)                                              (3)

The first two terms are the negative log of a Laplace kernel over the sensors, normalised
over them (``Z``: a person who could go to many sensors is less sure to fire any one of them;
a person silent for long, whose spread ``l`` grew, is less sure to fire next to where they
were). The last term (``w >= 0``, time scale ``tau``) is the cost of a silence: a person who
fired seconds ago is likelier to fire again than one silent for minutes (a renewal process
with a heavy-tailed gap, density ~ ``(1 + dt/tau)^-w``).

Births (eq. 4). A person appears at an entry/exit node (a door to the outside), or anywhere
in the first ``start_window_s`` of the log (people already home when it starts), at cost
``birth_door``; anywhere else at ``birth_inside`` (someone hidden so far)::

    b(i) = birth_door    if s_i is an entry node or t_i - t_1 <= start_window_s
           birth_inside  otherwise                                                     (4)

A person's silence costs nothing beyond (3): tracks persist while silent (dwelling), and a
person who left through a door comes back through it (``d`` from the door is small).

Who fires (eq. 5, optional, ``rho > 0``). People take turns unevenly: the person who fired the
last event usually fires the next one too. With ``n`` people present, the person of event
``i - 1`` fires event ``i`` with probability ``rho``, each other one with ``(1 - rho) / (n -
1)``, a newcomer with ``(1 - rho) / n``::

    f(i) = -ln rho                      same person as event i - 1 (0 when n = 1)
           -ln((1 - rho) / (n - 1))     another person present
           -ln((1 - rho) / n)           a birth                                      (5)

It is the Occam factor of the number of people: a second person costs ``-ln rho`` on every
event the first one keeps firing, so a track that only steals a few of one person's returns
to a sensor does not pay.

Distances ``d`` are shortest paths over the site's sensor graph, each edge as long as the
straight line between its sensors (walls are respected when the graph respects them), or the
straight line itself (``distance = "straight"``); pairs the graph does not join use the
straight line.
"""

from __future__ import annotations

import numpy as np

from onebit.core.lazy import lazy_module

nx = lazy_module("networkx")


def node_distances(
    nodes: list[str], positions: dict[str, tuple[float, float]], edges: list[tuple[str, str]], *, how: str = "graph"
) -> np.ndarray:
    """Matrix ``D[a, b]`` (metres, site units) of distances between ``nodes`` (module docstring).

    ``how = "graph"``: shortest paths over ``edges`` weighted by their straight length,
    the straight line where no path joins a pair; ``"straight"``: the straight line.

    >>> D = node_distances(["a", "b", "c"], {"a": (0, 0), "b": (1, 0), "c": (1, 1)}, [("a", "b"), ("b", "c")])
    >>> D.round(3).tolist()
    [[0.0, 1.0, 2.0], [1.0, 0.0, 1.0], [2.0, 1.0, 0.0]]
    """
    xy = np.array([positions[n] for n in nodes], dtype=float).reshape(-1, 2)
    straight = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    if how == "straight" or not edges:
        return straight
    idx = {n: k for k, n in enumerate(nodes)}
    g = nx.Graph()
    g.add_nodes_from(range(len(nodes)))
    g.add_weighted_edges_from(
        (idx[a], idx[b], float(straight[idx[a], idx[b]])) for a, b in edges if a in idx and b in idx
    )
    out = straight.copy()
    for a, lengths in nx.all_pairs_dijkstra_path_length(g):
        for b, d in lengths.items():
            out[a, b] = d
    return out


def move_cost(
    dist: np.ndarray,
    src: np.ndarray,
    dst: np.ndarray,
    dt: np.ndarray,
    *,
    l0: float,
    v: float,
    l_max: float,
    w: float,
    tau: float,
) -> np.ndarray:
    """``c(j, i)`` of eq. (2)-(3) for links from nodes ``src`` to nodes ``dst`` (indices into the
    distance matrix ``dist``) after silences ``dt`` (>= 0); the kernel is normalised over the
    nodes, ``Z = sum_s exp(-dist[src, s] / l)``.

    >>> D = np.array([[0.0, 1.0], [1.0, 0.0]])
    >>> c = move_cost(D, np.array([0, 0]), np.array([0, 1]), np.array([0.0, 0.0]), l0=1.0, v=0.0, l_max=1.0, w=0.0, tau=1.0)
    >>> np.round(np.exp(-c), 6).sum()  # a distribution over the next node
    np.float64(1.0)
    """
    dt = np.maximum(dt, 0.0)
    ell = np.minimum(l0 + v * dt, l_max)
    log_z = np.log(np.exp(-dist[src] / ell[:, None]).sum(axis=1))
    return dist[src, dst] / ell + log_z + w * np.log1p(dt / tau)


def birth_cost(
    t: np.ndarray, is_entry: np.ndarray, *, t_first: float, start_window_s: float, door: float, inside: float
) -> np.ndarray:
    """``b(i)`` of eq. (4) for event times ``t`` and whether their node is an entry node.

    >>> birth_cost(np.array([0.0, 100.0, 100.0]), np.array([False, True, False]), t_first=0.0, start_window_s=60.0,
    ...            door=4.0, inside=15.0).tolist()
    [4.0, 4.0, 15.0]
    """
    free = is_entry | (t - t_first <= start_window_s)
    return np.where(free, door, inside)
