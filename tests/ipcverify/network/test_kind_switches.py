"""Layout rule: no switch on the network kind outside ipcverify/network/ (callers use the Engine interface).

A switch is a read of ``.lowrank`` (``config.lowrank``, ``mc.lowrank``, ...) or an
``isinstance``/``issubclass`` test against a class of a network kind (the torch networks, their
weights, their engines). Inside ``ipcverify/network/`` :func:`ipcverify.network.engine_for` is the
one place the kind is chosen; everywhere else ipcverify asks the engine.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3] / "ipcverify"
#: Classes whose ``isinstance`` test is a switch on the network kind.
KIND_CLASSES = frozenset(
    {
        "IPCNetwork",
        "LowRankEnsemble",
        "Network",
        "NetworkWeights",
        "ScoredNetwork",
        "InferenceEngine",
        "LowRankEngine",
    }
)


def _names(node: ast.expr) -> set[str]:
    """Class names in an ``isinstance`` second argument (a name, ``mod.Name`` or a tuple of them)."""
    if isinstance(node, ast.Name):
        return {node.id}
    if isinstance(node, ast.Attribute):
        return {node.attr}
    if isinstance(node, ast.Tuple):
        return set().union(*(_names(e) for e in node.elts)) if node.elts else set()
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitOr):  # X | Y
        return _names(node.left) | _names(node.right)
    return set()


def kind_switches(source: str, filename: str = "<source>") -> list[str]:
    """Every switch on the network kind in ``source``, as ``file:line: what``."""
    found = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Attribute) and node.attr == "lowrank":
            found.append(f"{filename}:{node.lineno}: reads .lowrank")
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id in ("isinstance", "issubclass")
            and len(node.args) == 2
        ):
            hit = sorted(_names(node.args[1]) & KIND_CLASSES)
            if hit:
                found.append(f"{filename}:{node.lineno}: {node.func.id} on {', '.join(hit)}")
    return found


def test_the_checker_finds_planted_switches():
    planted = (
        "def f(model, net, eng):\n"
        "    if model.config.lowrank:\n"
        "        return 1\n"
        "    if isinstance(net, (IPCNetwork, LowRankEnsemble)):\n"
        "        return 2\n"
        "    if isinstance(eng, network.LowRankEngine | InferenceEngine):\n"
        "        return 3\n"
        "    return isinstance(net, NetworkWeights)\n"
    )
    found = kind_switches(planted, "planted.py")
    assert found == [
        "planted.py:2: reads .lowrank",
        "planted.py:4: isinstance on IPCNetwork, LowRankEnsemble",
        "planted.py:6: isinstance on InferenceEngine, LowRankEngine",
        "planted.py:8: isinstance on NetworkWeights",
    ]
    # what is not a switch on the network kind
    clean = "def f(x, cfg):\n    return isinstance(x, (int, Box)) and cfg.kind and cfg.low_rank\n"
    assert kind_switches(clean) == []


def _library_modules() -> list[Path]:
    return sorted(p for p in ROOT.rglob("*.py") if "network" not in p.relative_to(ROOT).parts[:1])


def test_the_library_modules_are_found():
    modules = _library_modules()
    names = {p.relative_to(ROOT).as_posix() for p in modules}
    assert {"decision/_query.py", "contract/_model.py", "io/_onnx.py", "training/_train.py"} <= names
    assert not any(n.startswith("network/") for n in names)


@pytest.mark.parametrize("path", _library_modules(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_switch_on_the_network_kind_outside_the_network_package(path):
    found = kind_switches(path.read_text(), path.relative_to(ROOT.parent).as_posix())
    assert found == [], "use the engine (ipcverify.network.Engine, engine_for) instead:\n" + "\n".join(found)
