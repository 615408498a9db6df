"""Text and picture of a circuit: components, connections, causality (``hydroline circuit``).

The picture here is the graph of the circuit's signals (``--png``); the hydraulic schematic
with ISO 1219-1 symbols (``--schematic``) is :mod:`hydroline.circuit.schematic`.
"""
from __future__ import annotations

from .builder import Circuit
from .types import COMPONENT_TYPES

__all__ = ["type_name", "component_rows", "draw_circuit"]


def type_name(component) -> str:
    """The circuit-file type of a component (its class name when no type builds it).

    Parameters
    ----------
    component : Component
        The component

    Returns
    -------
    str
        Its type name, a key of :data:`~hydroline.circuit.types.COMPONENT_TYPES`, or its class
        name
    """
    for name, t in COMPONENT_TYPES.items():
        if type(component) is t.component:
            return name
    return type(component).__name__


def component_rows(circuit: Circuit) -> list[dict]:
    """One row per component: name, type, inputs and outputs (port -> signal), states.

    Parameters
    ----------
    circuit : Circuit
        The circuit

    Returns
    -------
    list of dict
        One row per component
    """
    rows = []
    for c in circuit.components:
        rows.append({"component": c.name, "type": type_name(c),
                     "inputs": {p: c.signal(p) for p in c.inputs},
                     "outputs": {p: c.signal(p) for p in c.outputs},
                     "feedthrough": bool(c.feedthrough), "states": len(c.states)})
    return rows


def draw_circuit(circuit: Circuit, path, title: str = "") -> None:
    """Draw the circuit graph to a PNG: components as boxes, one arrow per signal from the
    component that outputs it to each that reads it (the causality), labelled with the
    signal's quantity.

    Parameters
    ----------
    circuit : Circuit
        The circuit
    path : str or Path
        PNG file to write
    title : str
        Figure title
    """
    import networkx as nx

    from ..plotting import figure_title, new_figure, save_png, tight_layout

    g = nx.DiGraph()
    for c in circuit.components:
        g.add_node(c.name, kind=type_name(c))
    labels = {}
    for row in circuit.connection_table():
        if row["producer"] is None:
            continue
        src = row["producer"].rsplit(".", 1)[0]
        for cons in row["consumers"]:
            dst = cons.rsplit(".", 1)[0]
            if src != dst:
                g.add_edge(src, dst)
                labels.setdefault((src, dst), []).append(row["quantity"][0])
    pos = nx.kamada_kawai_layout(g) if len(g) > 1 else {n: (0.0, 0.0) for n in g}
    n = len(g)
    fig = new_figure((max(8, 0.9 * n), max(6, 0.6 * n)))
    ax = fig.subplots()
    colors = {"hose": "#9ecae1", "servovalve": "#fdae6b", "actuator": "#a1d99b",
              "accumulator": "#dadaeb", "pressure_source": "#fc9272", "pump": "#fc9272"}
    nx.draw_networkx_edges(g, pos, ax=ax, arrows=True, arrowstyle="-|>", arrowsize=12,
                           edge_color="#555555", node_size=1800, connectionstyle="arc3,rad=0.08")
    nx.draw_networkx_nodes(g, pos, ax=ax, node_shape="s", node_size=1800,
                           node_color=[colors.get(g.nodes[v]["kind"], "#eeeeee") for v in g])
    nx.draw_networkx_labels(g, pos, ax=ax, font_size=7,
                            labels={v: f"{v}\n({g.nodes[v]['kind']})" for v in g})
    nx.draw_networkx_edge_labels(g, pos, ax=ax, font_size=6,
                                 edge_labels={e: ",".join(sorted(set(q))) for e, q in labels.items()})
    ax.set_title(figure_title(title or "circuit: arrows from the component that outputs a signal "
                              "to its readers (p pressure, f flow/force, c current, v velocity)"),
                 fontsize=9)
    ax.axis("off")
    tight_layout(fig)
    save_png(fig, path, dpi=120)
