"""Genome: head/tail rule, Karva decoding, PreHeader linking, JSON (paper section 3.1)."""

import json

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from coursekit.pictures import primitives as P
from coursekit.pictures.genome import Chromosome, ChromosomeString, Genome, FORMAT

C = Chromosome


def s(head_length, *symbols):
    return ChromosomeString(head_length, tuple(C.random(np.random.default_rng(0), n) for n in symbols))


def assert_valid(g: Genome):
    """Independent check of the paper's rules on a genome."""
    n = max(P.arity(name) for name in P.names())
    for string in g.strings:
        h = string.head_length
        assert len(string.symbols) == h + h * (n - 1) + 1
        assert all(P.arity(sym) == 0 for sym in string.symbols[h:])
    assert len(g.preheader) == len(g.strings) - 1
    # the Karva reading of every string ends inside the string
    for string in g.strings:
        need, i = 1, 0
        while need:
            need += P.arity(string.symbols[i]) - 1
            i += 1
        assert i <= len(string.symbols)


def test_primitive_set_covers_the_paper_and_sims():
    names = P.names()
    assert len(names) >= 30
    assert sum(P.get(n).sims for n in names) >= 20
    # every example the seed names for ZeroArgChrom, OneArgChrom and TwoArgChrom
    for name in ["const", "bw-noise", "turbulence", "ramp", "abs", "sin", "cos", "swirl",
                 "plus", "mod", "xor", "warp-swirl", "color", "x", "y", "pixmap", "gradient"]:
        assert name in names
    assert {P.arity(n) for n in names} == {0, 1, 2}
    assert P.arity("swirl") == 1 and P.arity("xor") == 2 and P.arity("x") == 0
    with pytest.raises(ValueError, match="unknown name 'nope'"):
        P.arity("nope")


def test_karva_reading_order_breadth_first():
    # plus takes sin and x; then sin takes y; const is non-coding
    g = Genome((s(2, "plus", "sin", "x", "y", "const"),))
    assert g.expression() == "(plus (sin y) x)"
    assert g.active == {"pre": [], 0: [0, 1, 2, 3]}
    # deeper: times(minus(x, y), abs(radius)) read level by level
    g = Genome((s(3, "times", "minus", "abs", "x", "y", "radius", "angle"),))
    assert g.expression() == "(times (minus x y) (abs radius))"
    assert g.active[0] == [0, 1, 2, 3, 4, 5]


def test_preheader_links_strings_as_its_tail():
    a = s(1, "sin", "x", "y")
    b = s(1, "abs", "y", "x")
    c = s(1, "x", "y", "y")
    g = Genome((a, b, c), (C("plus"), C("minus")))
    # PreHeader plus, minus then strings 0,1,2: plus(minus, S0), minus(S1, S2)
    assert g.expression() == "(plus (minus (abs y) x) (sin x))"
    assert g.active == {"pre": [0, 1], 0: [0, 1], 1: [0, 1], 2: [0]}
    # a terminal at the PreHeader root silences every string (kept, non-coding)
    g2 = Genome((a, b, c), (C("x"), C("minus")))
    assert g2.expression() == "x"
    assert g2.active == {"pre": [0], 0: [], 1: [], 2: []}


def test_non_coding_chromosomes_become_active_after_rotation():
    g = Genome((s(2, "x", "sin", "y", "radius", "angle"),))
    assert g.active[0] == [0]
    rotated = Genome((s(2, "sin", "x", "y", "radius", "angle"),))
    assert rotated.expression() == "(sin x)"


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_strings=st.integers(1, 6), h=st.integers(1, 8))
def test_random_genomes_obey_head_tail_rule_and_round_trip(seed, n_strings, h):
    g = Genome.random(np.random.default_rng(seed), n_strings=n_strings, head_length=h)
    assert_valid(g)
    assert all(st_.head_length == h and st_.tail_length == h + 1 for st_ in g.strings)
    text = g.to_json()
    assert json.loads(text)["format"] == FORMAT
    assert json.loads(text)["expression"] == g.expression()
    assert Genome.from_json(text) == g
    assert Genome.from_json(text).expression() == g.expression()
    assert g.size() == sum(len(v) for v in g.active.values())


def test_same_seed_same_genome():
    a = Genome.random(np.random.default_rng(7), n_strings=4, head_length=5)
    b = Genome.random(np.random.default_rng(7), n_strings=4, head_length=5)
    assert a.to_json() == b.to_json()


def test_random_respects_symbol_subset():
    g = Genome.random(np.random.default_rng(1), symbols=["plus", "x", "y"], n_strings=2)
    assert set(sum((st_.symbols for st_ in g.strings), [])) <= {"plus", "x", "y"}
    with pytest.raises(ValueError, match="no ZeroArgChrom"):
        Genome.random(np.random.default_rng(1), symbols=["plus"])


def test_constructors_refuse_invalid_genomes():
    with pytest.raises(ValueError, match="tail"):
        ChromosomeString(1, (C("sin"), C("plus"), C("x")))
    with pytest.raises(ValueError, match="length 2"):
        ChromosomeString(1, (C("sin"), C("x")))
    with pytest.raises(ValueError, match="head_length"):
        ChromosomeString(0, (C("x"),))
    with pytest.raises(ValueError, match="params has 0 values"):
        C("const")
    with pytest.raises(ValueError, match="preheader: 0 chromosomes"):
        Genome((s(1, "x", "y", "x"), s(1, "x", "y", "x")))
    with pytest.raises(TypeError, match=r"strings: expected a list of ChromosomeStrings \(e.g. Genome\(\[s\]\)\), got ChromosomeString"):
        Genome(s(1, "x", "y", "x"))  # one string, not in a list
    with pytest.raises(TypeError, match="rng"):
        Genome.random(7)
    with pytest.raises(TypeError, match="rng: expected numpy.random.Generator, got NoneType"):
        ChromosomeString.random(None, 2)
    with pytest.raises(ValueError, match="function_rate: '0.5' must lie in"):
        Genome.random(np.random.default_rng(0), function_rate="0.5")
    with pytest.raises(TypeError, match="symbols: expected a list of primitive names, got the string 'sin'"):
        Genome.random(np.random.default_rng(0), symbols="sin")
    g = Genome.random(np.random.default_rng(0))
    for k in (3, -4, "a", None):
        with pytest.raises(ValueError, match="k: .* must be 'pre' or the index of one of the 3 strings"):
            g.replace_string(k, g.strings[0])
    assert g.replace_string(-1, g.strings[0]).strings[-1] == g.strings[0]


@pytest.mark.parametrize("text, match", [
    ('{"format": "coursekit.genome/1", "strings": [', "not valid JSON"),
    ('{"format": "coursekit.creature/1", "strings": [], "preheader": []}', "format"),
    ('[1, 2]', "JSON object"),
    ('{"format": "coursekit.genome/1", "preheader": [], "strings": [{"head_length": 1, '
     '"chromosomes": [["sin", []], ["plus", []], ["x", []]]}]}', "tail"),
    ('{"format": "coursekit.genome/1", "preheader": [], "strings": [{"head_length": 1, '
     '"chromosomes": [["blah", []], ["x", []], ["x", []]]}]}', "unknown name 'blah'"),
    ('{"format": "coursekit.genome/1", "preheader": [], "strings": [{"head_length": 1, '
     '"chromosomes": [["const", [1, 2]], ["x", []], ["x", []]]}]}', "params has 2 values"),
])
def test_from_json_refuses_broken_or_foreign_text(text, match):
    with pytest.raises(ValueError, match=match):
        Genome.from_json(text)


# ---- bad genomes are refused, naming the field --------------------------------------------------

def test_overflowing_parameters_are_refused_naming_the_field():
    from coursekit.pictures import render

    with pytest.raises(ValueError, match=r"chromosome 'blur': sigma = 1e\+200 must be finite"):
        C("blur", (1e200,))
    with pytest.raises(ValueError, match="chromosome 'const': value = 1000"):
        C("const", (10**400,))                           # an integer too big for a float
    g = Genome.random(np.random.default_rng(0), n_strings=1, head_length=2)
    d = g.to_dict()
    d["strings"][0]["chromosomes"][-1] = ["const", [10**400]]
    with pytest.raises(ValueError, match=r"strings\[0\]\.chromosomes\[4\]: chromosome 'const': value"):
        Genome.from_json(json.dumps(d))                  # "1000...0" in the file: ValueError, not OverflowError
    d["strings"][0]["chromosomes"][-1] = ["const", [1e400]]  # json writes Infinity
    with pytest.raises(ValueError, match=r"chromosomes\[4\]"):
        Genome.from_json(json.dumps(d))
    edge = Genome((ChromosomeString(1, (C("blur", (3.4e38,)), C("x"), C("y"))),))
    assert np.isfinite(render(edge, 8)).all()          # the largest allowed value renders


def test_deep_nesting_is_refused_and_the_deepest_allowed_genome_works(tmp_path):
    from coursekit.pictures import render, save_image, load_genome
    from coursekit.pictures.genome import MAX_DEPTH

    def chain(n):  # n nested sin over x: n + 1 levels
        return Genome((ChromosomeString(n, tuple([C("sin")] * n + [C("x")] * (n + 1))),))
    with pytest.raises(ValueError, match=f"333 levels deep; at most {MAX_DEPTH}"):
        chain(332)
    deepest = chain(MAX_DEPTH - 1)
    assert deepest.depth() == MAX_DEPTH
    assert Genome.from_json(deepest.to_json()) == deepest
    assert load_genome(save_image(tmp_path / "deep.png", deepest, 8)) == deepest
    assert np.isfinite(render(deepest, 8)).all()
    with pytest.raises(ValueError, match="nested too deeply"):
        Genome.from_json("[" * 100_000 + "]" * 100_000)


def test_render_sizes_above_the_cap_get_a_clear_message():
    from coursekit.pictures import render

    g = Genome.random(np.random.default_rng(1))
    with pytest.raises(ValueError, match=r"size: 4097 x 4096 is 16,781,312 pixels; a picture has at most 16,777,216"):
        render(g, (4097, 4096))


def test_a_genome_decodes_once_and_shares_the_trees_of_the_strings_it_shares():
    import pickle

    g = Genome.random(np.random.default_rng(5), n_strings=3, head_length=4)
    tree = g.decode()
    assert g.decode() is tree
    fresh = Genome.from_json(g.to_json())  # equal, never decoded
    assert fresh.decode() == tree and fresh.decode() is not tree
    s = g.strings[1]
    chroms = list(s.chromosomes)
    chroms[0] = Chromosome("x") if chroms[0].symbol != "x" else Chromosome("y")
    child = g.replace_string(1, s.replace(chroms))
    roots = {node.site[0]: node for node in tree.walk() if node.site[1] == 0}
    child_roots = {node.site[0]: node for node in child.decode().walk() if node.site[1] == 0}
    for k in (0, 2):
        if k in roots:
            assert child_roots[k] is roots[k]  # the same string, the same subtree
    if 1 in roots:
        assert child_roots.get(1) is not roots[1]
    assert child.decode() == Genome.from_json(child.to_json()).decode()
    # what is kept with a genome never travels in a pickle
    back = pickle.loads(pickle.dumps(g))
    assert back == g and not any(k.startswith("_") for k in vars(back))
    assert not any(k.startswith("_") for s in back.strings for k in vars(s))
