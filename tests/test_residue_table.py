"""Residue lines interpolated over the dissipation number (hydroline.lines.residue_table, a
sweep's lines) against the same lines realised directly (issue 25).

The reference is :func:`residue_realisation` of each line itself; the nodes of the table
are realised for other lengths (and, in one test, another hose and oil), so the test checks
both that the realisation in the line's own units depends on Dn alone and that the
interpolation stays within its tolerance where a stencil moves to the next node or the
number of viscous clusters changes (the boundaries from SciPy's zeros of J2, not from the
code under test).
"""
import numpy as np
import pytest
from scipy import special

from hydroline import Fluid
from hydroline.lines import Line, ModalLine, residue_table
from hydroline.lines.corrections import kept_in_memory
from hydroline.lines.residue import MAX_VISCOUS_CLUSTERS, residue_realisation

OIL = Fluid(870.0, 3.2e-5, 1.5e9)
OTHER_OIL = Fluid(850.0, 4.6e-5, 1.7e9)


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    """An empty cache and no nodes in memory: every node realised here."""
    monkeypatch.setenv("HYDROLINE_CACHE_DIR", str(tmp_path))
    residue_table._NODES.clear()
    residue_table._SHARED.clear()
    residue_table._STENCILS.clear()


def with_dn(diameter, fluid, bulk_modulus, dn):
    """The line of this bore and oil whose dissipation number is dn, [-]."""
    probe = Line(1.0, diameter, fluid, bulk_modulus=bulk_modulus)
    return Line(dn / probe.dissipation_number, diameter, fluid, bulk_modulus=bulk_modulus)


def direct(line, form):
    with kept_in_memory():                       # (no cache file per line)
        return residue_realisation(line, 6, form)


def row_error(got, ref):
    """Largest difference in a state equation's row of [A, B], relative to the row's
    largest entry, and whether C, D and the state names are the same."""
    A, B, C, D, names = got
    Ar, Br, Cr, Dr, nr = ref
    row = np.maximum(np.abs(Ar).max(axis=1), np.abs(Br).max(axis=1))
    err = np.maximum(np.abs(A - Ar).max(axis=1), np.abs(B - Br).max(axis=1)) / row
    return err.max(), names == nr and np.array_equal(C, Cr) and np.array_equal(D, Dr)


def cluster_boundary(n_modes, clusters):
    """Dn at which a residue line of n modes (PQ) resolves one viscous cluster fewer than
    ``clusters``: ``j_{2,K}^2 Dn = theta_{n+1}``, theta = (n + 1/2) pi."""
    return (n_modes + 0.5) * np.pi / special.jn_zeros(2, clusters)[-1] ** 2


@pytest.mark.parametrize("form", ["PQ", "QP"])
def test_interpolated_line_is_the_direct_one_across_node_and_cluster_boundaries(form):
    """Lengths on both sides (1e-9 apart in Dn) of a node where the stencil moves on and of
    a change of the cluster count, and a spread of lengths 0.05-3 m of the rig's supply
    hose: the interpolated matrices are the direct ones to TOLERANCE of each row; on the
    two sides of the cluster boundary the direct lines differ by more (the count's jump,
    which the table follows)."""
    d, beta = 0.01343, 1.2e9
    node = 10.0 ** (-55 / residue_table.NODES_PER_DECADE)           # Dn 3.6e-4
    edge = cluster_boundary(6, 30)                                   # 30 -> 29 clusters
    dns = [node * (1 - 1e-9), node * (1 + 1e-9), edge * (1 - 1e-9), edge * (1 + 1e-9)]
    probe = Line(1.0, d, OIL, bulk_modulus=beta).dissipation_number
    dns += list(probe * np.array([0.05, 0.31, 0.77, 1.43, 2.2, 3.048]))
    got = {}
    for dn in dns:
        line = with_dn(d, OIL, beta, dn)
        table = residue_table.interpolated_realisation(line, 6, form)
        assert table is not None, dn
        ref = got[dn] = direct(line, form)
        err, same = row_error(table, ref)
        assert same and err <= residue_table.TOLERANCE, (dn, err)
    jump, _ = row_error(got[dns[2]], got[dns[3]])
    assert jump > 10 * residue_table.TOLERANCE       # the direct line's own jump there


def test_nodes_of_one_hose_serve_another_of_the_same_dissipation_number():
    """The realisation in the line's own units (tau, Z0) depends on Dn alone: nodes realised
    for one hose and oil, then a hose of another bore, oil and modulus at Dn between them
    is its own direct realisation to TOLERANCE."""
    dn = 1.234e-3
    first = with_dn(0.01343, OIL, 1.2e9, dn * 1.0001)
    assert residue_table.interpolated_realisation(first, 6, "PQ") is not None
    kept = set(residue_table._NODES)
    other = with_dn(0.0254, OTHER_OIL, 0.9e9, dn)
    table = residue_table.interpolated_realisation(other, 6, "PQ")
    assert set(residue_table._NODES) == kept                 # no node realised anew
    err, same = row_error(table, direct(other, "PQ"))
    assert same and err <= residue_table.TOLERANCE


def test_other_forms_and_viscoelastic_walls_are_left_to_the_direct_realisation(monkeypatch):
    """PP, QQ and viscoelastic walls are not tabulated; nor is a line whose stencil holds a
    node whose tail fit came near its envelope bound (here: every node, the limit at 0), and
    a ModalLine in the sweep's context is then the direct realisation."""
    line = Line(1.0, 0.01343, OIL, bulk_modulus=1.2e9)
    assert residue_table.interpolated_realisation(line, 6, "PP") is None
    assert residue_table.interpolated_realisation(line, 6, "QQ") is None
    wall = Line(1.0, 0.01343, OIL, bulk_modulus=1.2e9, creep_compliances=(1e-10,),
                retardation_times=(0.01,))
    assert residue_table.interpolated_realisation(wall, 6, "PQ") is None
    monkeypatch.setattr(residue_table, "TAIL_PEAK_LIMIT", 0.0)
    assert residue_table.interpolated_realisation(line, 6, "PQ") is None
    with kept_in_memory(), residue_table.interpolated_lines():
        model = ModalLine(line, 6, "PQ", method="residue")
    ref = direct(line, "PQ")
    assert np.array_equal(model.A, ref[0]) and np.array_equal(model.B, ref[1])


def test_modal_line_interpolates_only_inside_the_context():
    line = Line(1.7, 0.01343, OIL, bulk_modulus=1.2e9)
    with kept_in_memory():
        outside = ModalLine(line, 6, "PQ", method="residue")
        with residue_table.interpolated_lines():
            inside = ModalLine(line, 6, "PQ", method="residue")
    ref = direct(line, "PQ")
    assert np.array_equal(outside.A, ref[0]) and np.array_equal(outside.B, ref[1])
    table = residue_table.interpolated_realisation(line, 6, "PQ")
    assert np.array_equal(inside.A, table[0]) and np.array_equal(inside.B, table[1])
    assert not residue_table.in_use()
    assert MAX_VISCOUS_CLUSTERS >= 30          # (the boundary tested above exists)


def test_nodes_read_back_from_the_cache_give_the_same_line(monkeypatch):
    """A later process (here: the memory cleared) reads the nodes from the on-disk cache and
    realises none: the same matrices bit for bit."""
    line = Line(0.8123, 0.01343, OIL, bulk_modulus=1.2e9)
    first = residue_table.interpolated_realisation(line, 6, "QP")
    for kept in (residue_table._NODES, residue_table._SHARED, residue_table._STENCILS):
        kept.clear()
    monkeypatch.setattr(residue_table, "realisation_with_notes",
                        lambda *a: pytest.fail("a node realised again"))
    again = residue_table.interpolated_realisation(line, 6, "QP")
    for a, b in zip(first[:4], again[:4]):
        assert np.array_equal(a, b)
    assert first[4] == again[4]


@pytest.mark.parametrize("n_modes", [6, 10])
def test_qp_nodes_are_the_pq_nodes_seen_from_the_other_end(monkeypatch, n_modes):
    """A QP line is the PQ line mirrored (ends exchanged, flows' signs changed): its nodes
    are the PQ nodes' states permuted and signed, equal to QP's own realisation to rounding
    (1e-12 of each row, far inside TOLERANCE), and no QP node is realised."""
    from hydroline.lines.residue import viscous_clusters

    realised = []
    real = residue_table.realisation_with_notes
    monkeypatch.setattr(residue_table, "realisation_with_notes",
                        lambda line, n, form, *a: realised.append(form) or real(line, n, form, *a))
    d, beta = 0.01343, 1.2e9
    for i in (-70, -55, -41, -30):                   # Dn 4e-5 ... 1.3e-2
        line = with_dn(d, OIL, beta, 10.0 ** (i / residue_table.NODES_PER_DECADE))
        clusters = viscous_clusters(line, n_modes, "QP")
        assert clusters == viscous_clusters(line, n_modes, "PQ")
        got = residue_table._node(line, n_modes, "QP", clusters, i)
        with kept_in_memory():
            ref = residue_table._realised_node(line, n_modes, "QP", clusters, i)
        assert got[0] == ref[0] and got[4] == ref[4] and np.array_equal(got[3], ref[3])
        row = np.maximum(np.abs(ref[1]).max(axis=1), np.abs(ref[2]).max(axis=1))
        err = np.maximum(np.abs(got[1] - ref[1]).max(axis=1),
                         np.abs(got[2] - ref[2]).max(axis=1)) / row
        assert err.max() <= 1e-12, (i, err.max())
    assert realised == ["PQ", "QP"] * 4              # the table's PQ, the reference's QP
