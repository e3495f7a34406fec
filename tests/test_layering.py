"""The code's shape holds: imports point down (backend → device_bridge → controller_core), the lab stands apart from
the product, the leg's own code never reaches the model, storage leaves the rules and the screens to the services, no
module imports one that imports it back (Python and the dashboard's JavaScript), no private name crosses a module, and
no dashboard page imports another page or the router."""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("controller_core", "device_bridge", "backend", "lab", "benchmarks", "tests")
LAYER = {"controller_core": 0, "device_bridge": 1, "backend": 2}


@functools.cache
def _tree(path: Path) -> ast.Module:
    """A module's syntax tree, parsed once per test process (several tests read every module; never modified)."""
    return ast.parse(path.read_text())


def _python_modules() -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = path
    return out


def _module_imports(modules: dict[str, Path]) -> dict[str, list[tuple[str, str]]]:
    """Per module, its module-level imports of our modules as (module, name) (``if TYPE_CHECKING`` left out)."""
    out: dict[str, list[tuple[str, str]]] = {}
    for name, path in modules.items():
        found = []
        for node in _tree(path).body:
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    if full in modules:
                        found.append((full, ""))
                    elif node.module in modules:
                        found.append((node.module, alias.name))
            elif isinstance(node, ast.Import):
                found += [(alias.name, "") for alias in node.names if alias.name in modules]
        out[name] = found
    return out


def _every_import(modules: dict[str, Path]) -> dict[str, set[str]]:
    """Per module, every module of ours it imports anywhere (inside functions too: a lazy import is still a use)."""
    out: dict[str, set[str]] = {}
    for name, path in modules.items():
        found = set()
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                found |= {f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in modules else node.module
                          for a in node.names if node.module in modules or f"{node.module}.{a.name}" in modules}
            elif isinstance(node, ast.Import):
                found |= {a.name for a in node.names if a.name in modules}
        out[name] = found
    return out


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    colour: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(u: str) -> None:
        colour[u] = 1
        stack.append(u)
        for v in sorted(graph.get(u, ())):
            if colour.get(v) == 1:
                found.append([*stack[stack.index(v):], v])
            elif not colour.get(v):
                visit(v)
        stack.pop()
        colour[u] = 2

    for node in sorted(graph):
        if not colour.get(node):
            visit(node)
    return found


def test_python_imports_point_down_and_never_close_a_circle():
    modules = _python_modules()
    every = _every_import(modules)
    upward = [(m, target) for m, found in every.items() for target in found
              if m.split(".")[0] in LAYER and target.split(".")[0] in LAYER
              and LAYER[target.split(".")[0]] > LAYER[m.split(".")[0]]]
    assert upward == []
    # every import counts for a circle: at module level, under ``if TYPE_CHECKING`` (a type's use is a use) and inside
    # functions (a lazy import that closes a circle only hides it until the day it runs first)
    assert _cycles({m: found - {m} for m, found in every.items()}) == []


def test_the_lab_stands_apart_from_the_product():
    every = _every_import(_python_modules())
    lab_uses_backend = sorted((m, t) for m, found in every.items() if m.split(".")[0] == "lab"
                              for t in found if t.split(".")[0] == "backend")
    assert lab_uses_backend == []
    product_uses_lab = sorted((m, t) for m, found in every.items() if m.split(".")[0] in LAYER
                              for t in found if t.split(".")[0] in ("lab", "benchmarks", "tests"))
    assert product_uses_lab == []    # the lab's commands join `quasitune` through an entry point (lab/cli.py)


def test_the_legs_own_code_never_reaches_the_model():
    every = _every_import(_python_modules())
    reaching = sorted((m, t) for m, found in every.items() if m.startswith("device_bridge")
                      and not m.startswith("device_bridge.bench") for t in found
                      if t in ("controller_core.model", "controller_core.model_io", "controller_core"))
    assert reaching == []


# what the leg's computer runs (issue 54): the firmware and its link, the OSL adapter, its loop and calibration
LEG_MODULES = ("device_bridge.firmware", "device_bridge.device_node", "device_bridge.mqtt_bus", "device_bridge.gateway",
               "device_bridge.osl.config", "device_bridge.osl.leg", "device_bridge.osl.loop",
               "device_bridge.osl.calibration")
_BLOCKER = """
import importlib, importlib.abc, sys
BLOCKED = {"sklearn", "scipy", "fastapi", "starlette", "sqlalchemy", "alembic", "mujoco", "uvicorn", "matplotlib"}
class Blocker(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"the leg imported {name}")
sys.meta_path.insert(0, Blocker())
for m in sys.argv[1:]:
    importlib.import_module(m)
"""


def test_the_legs_modules_load_without_the_model_the_server_or_the_bench():
    """The leg installs only ``.[leg]``: its modules import no scikit-learn, SciPy, FastAPI, SQLAlchemy or MuJoCo
    (checked in a fresh interpreter that refuses them)."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-c", _BLOCKER, *LEG_MODULES], cwd=ROOT, capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr[-2000:]


# what storage leaves to the service layer (backend/services) and the screens: the rules (the device-side check, the
# bench's verdict and its figures) and the words and shapes a page or the API shows
NOT_FOR_STORAGE = ("backend.services", "backend.bench", "backend.routers", "backend.schemas", "backend.clinical_words",
                   "backend.refusal_words", "device_bridge.as_run")


def test_storage_stores_and_leaves_the_rules_and_the_screens_to_the_services():
    every = _every_import(_python_modules())
    reaching = sorted((m, t) for m, found in every.items() if m.startswith("backend.store")
                      for t in found if t.startswith(NOT_FOR_STORAGE))
    assert reaching == []


def test_no_private_name_is_imported_from_another_module():
    modules = _python_modules()
    crossing = [(m, target, name) for m, found in _module_imports(modules).items() for target, name in found
                if name.startswith("_") and not name.startswith("__") and target != m]
    assert crossing == []


_JS_IMPORT = re.compile(r"""^\s*import\s+(?:[^"']*?\s+from\s+)?["'](\.[^"']+)["']""", re.M)


def test_the_dashboard_modules_form_no_circle_and_pages_import_no_page_nor_the_router():
    app = (ROOT / "frontend" / "app").resolve()
    graph = {path: {(path.parent / dep).resolve() for dep in _JS_IMPORT.findall(path.read_text())}
             for path in app.rglob("*.js")}
    missing = [(str(a.relative_to(app)), str(b)) for a, deps in graph.items() for b in deps if not b.exists()]
    assert missing == []
    named = {str(k.relative_to(app)): {str(d.relative_to(app)) for d in v} for k, v in graph.items()}
    assert _cycles(named) == []
    pages = {k: v for k, v in named.items() if k.startswith("pages/")}
    assert {k: sorted(d for d in v if d.startswith("pages/") or d == "main.js") for k, v in pages.items()} == {
        k: [] for k in pages}
