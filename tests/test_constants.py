"""Every numeric constant in recon/ says in a comment what it scales with, and no comment cites a benchmark mesh."""

from bench.list_constants import main


def test_every_constant_has_a_reason_and_no_comment_names_a_benchmark_mesh(capsys):
    code = main(["--check"])
    assert code == 0, capsys.readouterr().out


def test_the_check_sees_mesh_names_and_leaves_other_words():
    from bench.list_constants import MESH_NAMES

    for text in ("tuned on rocker-arm2500", "the casting's fillet", "the ABC model", "abc_00000050", "joint"):
        assert MESH_NAMES.search(text), text
    for text in ("a thousandth of the diagonal", "jointly", "collections.abc", "-0.0 → 0.0"):
        assert not MESH_NAMES.search(text), text
