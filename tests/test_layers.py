"""The layers import one way: solvers <- model <- app <- studies (the CLI's ``handeye study`` aside).

Every module's imports are read with ``ast`` (module level and inside functions), so an import
against the order fails here before it ties the layers together. ``solvers`` knows nothing of
robots, ``model`` nothing of the application, the application nothing of the studies; the
package root (the public API) is part of the application layer.
"""
import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: folder -> (layer name, rank); a module may import its own rank or lower ones
LAYERS = {"solvers": 0, "model": 1, "app": 2, "studies": 3}
#: the one allowed upward import: the CLI runs a study only when asked (``handeye study``)
ALLOWED_UPWARD = {("app/command/cli.py", "_study", "handeye.studies")}


def _modules():
    out = [ROOT / "__init__.py"]
    for folder in LAYERS:
        out += sorted((ROOT / folder).rglob("*.py"))
    return out


def _layer_of_module(name):
    """Rank of an imported module name, or None when it is not handeye's."""
    parts = name.split(".")
    if parts[0] != "handeye":
        return None
    if len(parts) == 1 or parts[1] not in LAYERS:
        return LAYERS["app"]  # the package root and its names are the public API: application layer
    return LAYERS[parts[1]]


def _imports(tree):
    """(imported module, enclosing function name or None) for every import in a module."""
    found = []

    def visit(node, function):
        for child in ast.iter_child_nodes(node):
            name = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
            if isinstance(child, ast.Import):
                found.extend((a.name, function) for a in child.names)
            elif isinstance(child, ast.ImportFrom):
                assert child.level == 0, "relative imports: use handeye.<layer>.<module>"
                if child.module == "handeye":  # from handeye import solvers (a layer) or calibrate (the API)
                    found.extend((f"handeye.{a.name}", function) for a in child.names)
                else:
                    found.append((child.module, function))
            visit(child, name)

    visit(tree, None)
    return found


def _own_rank(path):
    rel = path.relative_to(ROOT)
    return LAYERS["app"] if rel.parts == ("__init__.py",) else LAYERS[rel.parts[0]]


@pytest.mark.parametrize("path", _modules(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_imports_point_down_the_layers(path):
    rank = _own_rank(path)
    rel = path.relative_to(ROOT).as_posix()
    for name, function in _imports(ast.parse(path.read_text(), rel)):
        assert name.split(".")[0] not in ("model", "solvers", "studies", "app"), (
            f"{rel} imports {name!r}: the source folders install as handeye.<layer>, never top-level")
        target = _layer_of_module(name)
        if target is None or target <= rank:
            continue
        allowed = any(rel == f and function == fn and name.startswith(mod) for f, fn, mod in ALLOWED_UPWARD)
        assert allowed, f"{rel} imports {name} (inside {function or 'the module'}): against solvers <- model <- app <- studies"


def test_the_checker_sees_a_violation():
    """The test above would fail on an upward import (the checker is not vacuous)."""
    tree = ast.parse("def f():\n    from handeye.app import calibrate\n")
    assert _imports(tree) == [("handeye.app", "f")]
    assert _layer_of_module("handeye.app.engine.calibrate") > LAYERS["model"]
    assert _layer_of_module("handeye") == LAYERS["app"] == _layer_of_module("handeye.calibrate")
    assert _imports(ast.parse("from handeye import solvers")) == [("handeye.solvers", None)]
    assert _layer_of_module("numpy") is None


def test_importing_handeye_imports_no_study_and_no_sympy():
    """``import handeye`` is cheap and layered: no studies, no sympy, no casadi at import."""
    import subprocess
    import sys

    code = ("import sys, handeye; bad = sorted(m for m in sys.modules if m.startswith('handeye.studies') or "
            "m in ('sympy', 'casadi', 'matplotlib')); print(','.join(bad))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd="/")
    assert out.stdout.strip() == "", out.stdout


def test_importing_a_lower_layer_loads_nothing_above_it():
    """The package root is lazy (PEP 562): ``import handeye.solvers`` loads no model and no app,
    ``import handeye.model.fit.calibration`` no app."""
    import subprocess
    import sys

    code = ("import sys, importlib; importlib.import_module(sys.argv[1]); "
            "print(','.join(sorted({m.split('.')[1] for m in sys.modules if m.startswith('handeye.')})))")
    for module, allowed in (("handeye.solvers", {"solvers"}), ("handeye.model.fit.calibration", {"solvers", "model"})):
        out = subprocess.run([sys.executable, "-c", code, module], capture_output=True, text=True, check=True, cwd="/")
        assert set(filter(None, out.stdout.strip().split(","))) <= allowed, (module, out.stdout)


def _module_name(path):
    rel = path.relative_to(ROOT).with_suffix("")
    parts = ("handeye", *rel.parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph():
    """handeye module -> the handeye modules it imports (module level and inside functions).

    ``from handeye.x import y`` is an import of the module ``handeye.x.y`` when that is a module
    (a submodule), else of ``handeye.x``; a package's ``__init__`` is not implied by importing
    one of its modules (the usual convention of import linters)."""
    modules = {_module_name(p): p for p in _modules()}
    graph = {}
    for name, path in modules.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                deps |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module:
                subs = {f"{node.module}.{a.name}" for a in node.names} & set(modules)
                deps |= subs or {node.module}
        graph[name] = {d for d in deps if d in modules and d != name}
    return graph


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circles():
    """No module imports itself through others, not even lazily inside a function (a circle
    ties modules that should be separable: the engine to its reports, the symbolic source to
    the numeric modules generated from it)."""
    assert _cycles(_import_graph()) == []


def test_the_circle_finder_sees_a_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert _cycles(graph) == [["a", "b", "c"]]
    assert "handeye.app.engine.calibrate" in _import_graph()["handeye.app.public.api"]


# --- rooms and local imports (written by the rooms migration, issue 38; keep up to date by hand) ---

#: layer -> room (a subpackage, dotted below the layer) -> the rooms of the same layer it may import.
#: The rooms import one way (no cycle between them: test below); every module lives in a room.
ROOMS = {
    "model": {
        "chain": {"common"},
        "common": set(),
        "compiled": {"chain", "common", "fit"},
        "data": set(),
        "datasets": {"chain", "common", "fit", "geometry", "readers", "robot"},
        "design": {"chain", "common", "datasets", "effects", "fit", "geometry", "readers", "robot", "simulation"},
        "effects": {"chain", "robot"},
        "fit": {"chain", "common", "effects", "robot"},
        "geometry": {"common"},
        "readers": {"chain", "common"},
        "robot": {"chain", "common", "readers"},
        "simulation": {"chain", "common", "geometry", "readers", "robot"},
    },
    "app": {
        "command": {"common", "present", "tools"},
        "common": set(),
        "engine": {"common", "present"},
        "ingest": {"common", "engine", "present"},
        "outputs": {"common", "engine", "present"},
        "present": {"common"},
        "present.web": {"common", "outputs", "present"},
        "public": {"common", "engine", "outputs", "present", "present.web"},
        "tools": {"common", "engine", "present", "public"},
    },
}

#: every import inside a function body, (file, function, module) grouped by why it is not at module
#: level (anything else is imported at module level; test below)
LOCAL_IMPORTS = {
    "a test patches the imported name (monkeypatch): looked up at call time": [
        ("app/engine/problems.py", "chunked", "handeye.model.fit.calibration"),
        ("app/tools/bench.py", "pipeline", "handeye.app.engine.request"),
        ("app/tools/bench_points.py", "measure", "handeye.app.public.api"),
    ],
    "import cycle at load: what it imports imports this module (through a package's __init__)": [
        ("solvers/ipopt.py", "minimize_many", "handeye.solvers.batch"),
    ],
    "layers: the one upward import (ALLOWED_UPWARD), only when a study runs": [
        ("app/command/cli.py", "_study", "handeye.studies.study"),
    ],
    "optional dependency: imported where it is used, its absence handled there": [
        ("app/command/cli.py", "_bench", "scipy.optimize"),
        ("app/ingest/command.py", "_from_bag", "handeye.app.ingest.rosbag"),  # it imports rosbags; the request checks it is there
        ("app/present/interactive.py", "__init__", "ipywidgets"),
        ("app/present/interactive.py", "_widget", "ipywidgets"),
        ("app/present/web/view.py", "figure", "plotly.graph_objects"),
        ("app/present/web/view.py", "have_plotly", "plotly.graph_objects"),
        ("app/present/web/view.py", "plotly_js", "plotly.offline"),
        ("app/tools/bench.py", "scipy_fit", "scipy.optimize"),
        ("app/tools/bench_peers.py", "_ceres", "pyceres"),
        ("app/tools/bench_peers.py", "_gtsam_align", "gtsam"),
        ("app/tools/sweep.py", "_dask_client", "distributed"),
        ("app/tools/sweep.py", "run", "distributed"),
    ],
    "start-up: `handeye --help` loads no module it does not need (no numpy)": [
        ("app/command/cli.py", "_bench", "handeye.app.common.errors"),
        ("app/command/cli.py", "_bench", "handeye.app.tools.bench"),
        ("app/command/cli.py", "_bench", "handeye.app.tools.bench_solvers"),
        ("app/command/cli.py", "_guarded", "handeye.app.common.registry"),
        ("app/command/cli.py", "_guarded", "handeye.model.common.errors"),
        ("app/command/cli.py", "_result", "handeye.app.common.options"),
        ("app/command/cli.py", "_run", "handeye.model.datasets.dataset"),
        ("app/command/cli.py", "_sizes", "handeye.app.common.errors"),
        ("app/command/cli.py", "_study", "handeye.app.tools.sweep"),
        ("app/command/parser.py", "build_parser", "handeye.app.common.options"),
        ("app/command/parser.py", "dumps", "handeye.app.present.results"),
    ],
    "start-up: would load PIL at import, which the module does not load yet": [
        ("app/present/figure_style.py", "png_bytes", "PIL"),
    ],
    "start-up: would load casadi at import, which the module does not load yet": [
        ("app/tools/bench_pipeline.py", "_lean_user_solve", "casadi"),
        ("app/engine/problems.py", "testfunction_nlp", "casadi"),
        ("model/chain/codegen.py", "casadi_function", "casadi"),
        ("model/chain/testfunction.py", "casadi_function", "casadi"),
        ("model/compiled/fast.py", "_calibrate_python", "casadi"),
        ("model/compiled/fast.py", "_per_measurement", "casadi"),
        ("model/compiled/fast.py", "library", "casadi"),
        ("model/compiled/fast.py", "normal_equations", "casadi"),
        ("model/compiled/fast_starts.py", "_generated", "casadi"),
        ("model/fit/nlp_callback.py", "_callback_class", "casadi"),
        ("model/fit/nlp_problem.py", "_constraints", "casadi"),
        ("model/fit/nlp_problem.py", "_template", "casadi"),
        ("model/fit/nlp_problem.py", "_quadratic_template", "casadi"),
        ("model/fit/nlp_problem.py", "nlp", "casadi"),
        ("solvers/ipopt.py", "__init__", "casadi"),
        ("solvers/ipopt.py", "_recorder", "casadi"),
    ],
    "start-up: would load cycler at import, which the module does not load yet": [
        ("app/present/figure_style.py", "rc", "cycler"),
    ],
    "start-up: would load handeye modules at import that the module does not load yet": [
        ("app/common/arguments.py", "load_dataset", "handeye.model.datasets.dataset"),
        ("app/common/options.py", "_studies", "handeye.app.common.registry"),
        ("app/engine/cell_stage.py", "_other_mount_fits_better", "handeye.model.fit.global_fit"),
        ("app/engine/cell_stage.py", "held_contradicted", "handeye.app.engine.describe"),
        ("app/engine/command_request.py", "outputs_checked", "handeye.app.common.files"),
        ("app/engine/request.py", "_robot_effects_possible", "handeye.model.effects"),
        ("app/engine/set_aside.py", "_contradiction_error", "handeye.app.common.errors"),
        ("app/engine/set_aside.py", "_contradiction_error", "handeye.app.engine.request"),
        ("app/engine/set_aside.py", "exclude_inconsistent", "handeye.app.engine.request"),
        ("app/engine/set_aside.py", "exclude_inconsistent", "handeye.model.datasets.consistency"),
        ("app/engine/set_aside.py", "with_geometry", "handeye.model.geometry.arc_geometry"),
        ("app/engine/score.py", "compare", "handeye.app.present.score_results"),
        ("app/engine/score.py", "own_calibration", "handeye.app.engine.calibrate"),
        ("app/engine/score.py", "score_against", "handeye.app.engine.describe"),
        ("app/engine/score.py", "score_against", "handeye.app.present.score_results"),
        ("app/engine/slips.py", "_check_conventions", "handeye.app.engine.detective"),
        ("app/engine/slips.py", "check_diameter", "handeye.model.geometry.circle"),
        ("app/engine/slips.py", "_free_axes_fit", "handeye.app.engine.cell_stage"),
        ("app/outputs/commands.py", "_robot_values", "handeye.model.robot.robot_errors"),
        ("app/outputs/commands.py", "cloud", "handeye.model.datasets.scan"),
        ("app/outputs/commands.py", "cloud", "handeye.model.geometry.cloud"),
        ("app/outputs/commands.py", "robot_text", "handeye.model.robot.robot_errors"),
        ("app/outputs/commands.py", "robot_text", "handeye.model.robot.robots"),
        ("app/outputs/commands.py", "validate", "handeye.app.outputs.validate"),
        ("app/outputs/commands.py", "validate", "handeye.app.present.report"),
        ("app/outputs/commands.py", "validate", "handeye.model.datasets.dataset"),
        ("app/outputs/commands.py", "validate", "handeye.model.datasets.scan"),
        ("app/outputs/commands.py", "validate", "handeye.model.readers.tables"),
        ("app/outputs/saved.py", "_positioner", "handeye.model.chain.mounts"),
        ("app/outputs/saved.py", "_positioner", "handeye.model.readers.tables"),
        ("app/outputs/validate.py", "summary", "handeye.app.present.report"),
        ("app/present/diagnosis_results.py", "figures", "handeye.app.present.report"),
        ("app/present/diagnosis_results.py", "summary", "handeye.app.present.report"),
        ("app/present/figure_style.py", "save", "handeye.app.common.files"),
        ("app/present/protocol.py", "save", "handeye.app.common.files"),
        ("app/present/report.py", "_centres_seen", "handeye.app.present.figure_style"),
        ("app/present/report.py", "_bend_lines", "handeye.model.geometry.profile_bend"),
        ("app/present/report.py", "_effect_lines", "handeye.model.effects"),
        ("app/present/report.py", "_residual_bars", "handeye.app.present.figure_style"),
        ("app/present/report.py", "_saved", "handeye.app.present.figure_style"),
        ("app/present/report.py", "calibration_plot", "handeye.app.present.plotting"),
        ("app/present/report.py", "diagnosis_figures", "handeye.app.present.figure_style"),
        ("app/present/report.py", "diagnosis_figures", "handeye.app.present.plotting"),
        ("app/present/report.py", "validation_figure", "handeye.app.present.figure_style"),
        ("app/present/report.py", "validation_figure", "handeye.app.present.plotting"),
        ("app/present/result_parts.py", "user_poses", "handeye.model.chain.conventions"),
        ("app/present/result_parts.py", "user_poses", "handeye.model.chain.own_frame"),
        ("app/present/result_parts.py", "user_std", "handeye.model.chain.own_frame"),
        ("app/present/results.py", "in_user_frame", "handeye.model.chain.own_frame"),
        ("app/present/results.py", "in_user_frame", "handeye.model.chain.pose"),
        ("app/present/results.py", "summary", "handeye.app.present.report"),
        ("app/present/score_results.py", "summary", "handeye.app.present.report"),
        ("app/present/web/figures.py", "gap_steps", "handeye.app.present.report"),
        ("app/present/web/page.py", "build", "handeye.app.present.web.cell"),
        ("app/present/web/page.py", "snippets", "handeye.app.outputs.formats"),
        ("app/present/web/page.py", "snippets", "handeye.app.outputs.saved"),
        ("app/present/web/page.py", "snippets", "handeye.app.outputs.verdict"),
        ("app/present/web/parts.py", "header", "handeye.app.common.files"),
        ("app/present/web/parts.py", "header", "handeye.model.chain.mounts"),
        ("app/present/web/write.py", "write_report", "handeye.app.common.files"),
        ("app/present/web/write.py", "write_report", "handeye.app.outputs.saved"),
        ("app/present/web/write.py", "write_report", "handeye.app.present.web.page"),
        ("app/present/web/write.py", "write_report", "handeye.app.present.web.view"),
        ("app/public/api.py", "_diagnosed", "handeye.app.engine.agreement"),
        ("app/public/api.py", "_diagnosed", "handeye.app.engine.diagnose"),
        ("app/public/api.py", "_diagnosed", "handeye.app.engine.prepare"),
        ("app/public/api.py", "_diagnosed", "handeye.app.engine.search"),
        ("app/public/api.py", "_diagnosed", "handeye.app.engine.slips"),
        ("app/public/api.py", "_diagnosis_figures", "handeye.app.common.files"),
        ("app/public/api.py", "_diagnosis_figures", "handeye.app.present.report"),
        ("app/public/api.py", "_written", "handeye.app.common.files"),
        ("app/public/api.py", "_written", "handeye.app.engine.cell_stage"),
        ("app/public/api.py", "_written", "handeye.app.present.report"),
        ("app/public/api.py", "_written", "handeye.app.present.web.write"),
        ("app/public/api.py", "_calibrated", "handeye.app.engine.calibrate"),
        ("app/public/api.py", "_calibrated", "handeye.app.engine.classic"),
        ("app/public/api.py", "_calibrated", "handeye.app.engine.command_request"),
        ("app/public/api.py", "_calibrated", "handeye.app.engine.request"),
        ("app/public/api.py", "_calibrated", "handeye.app.engine.score"),
        ("app/public/api.py", "compare", "handeye.app.engine.command_request"),
        ("app/public/api.py", "compare", "handeye.app.engine.score"),
        ("app/public/api.py", "diagnose", "handeye.app.common.files"),
        ("app/public/api.py", "diagnose", "handeye.app.engine.command_request"),
        ("app/public/making.py", "_robot_plan", "handeye.model.design.planning_robot"),
        ("app/public/making.py", "_robot_summary", "handeye.model.design.planning_robot"),
        ("app/public/making.py", "_sensor_plan", "handeye.model.design.planning"),
        ("app/public/making.py", "plan", "handeye.app.common.files"),
        ("app/public/making.py", "plan", "handeye.app.engine.making_request"),
        ("app/public/making.py", "pose_list", "handeye.model.datasets.dataset"),
        ("app/public/making.py", "simulate", "handeye.app.common.files"),
        ("app/public/making.py", "simulate", "handeye.app.engine.making_request"),
        ("app/public/making.py", "simulate", "handeye.model.simulation.simulate"),
        ("app/public/reporting.py", "report", "handeye.app.public.api"),
        ("app/tools/bench.py", "plot", "handeye.app.present.figure_style"),
        ("app/tools/bench.py", "plot", "handeye.app.present.plotting"),
        ("app/tools/bench.py", "throughput", "handeye.app.tools.sweep"),
        ("app/tools/bench_guarantee.py", "_without_guarantee", "handeye.app.engine.guarantee"),
        ("app/tools/bench_guarantee.py", "_without_guarantee", "handeye.app.engine.slips"),
        ("app/tools/bench_guarantee.py", "measure", "handeye.app.engine.detective"),
        ("app/tools/bench_guarantee.py", "measure", "handeye.app.engine.guarantee"),
        ("app/tools/bench_pipeline.py", "_ipopt_from_scratch", "handeye.app.engine.problems"),
        ("app/tools/bench_pipeline.py", "_ipopt_from_scratch", "handeye.model.datasets.observations"),
        ("app/tools/bench_pipeline.py", "_ipopt_from_scratch", "handeye.solvers"),
        ("app/tools/bench_pipeline.py", "_stage_times", "handeye.app.engine.calibrate"),
        ("app/tools/bench_pipeline.py", "_stage_times", "handeye.app.engine.describe"),
        ("app/tools/bench_pipeline.py", "_stage_times", "handeye.app.engine.loo"),
        ("app/tools/bench_pipeline.py", "_whole", "handeye.app.engine.loo"),
        ("app/tools/bench_pipeline.py", "_stage_times", "handeye.app.engine.request"),
        ("app/tools/bench_pipeline.py", "_lean_user_solve", "handeye.model.chain.pose"),
        ("app/tools/bench_pipeline.py", "_lean_user_solve", "handeye.model.common.rotation"),
        ("app/tools/bench_pipeline.py", "pipeline_vs_solve", "handeye.app.engine.calibrate"),
        ("app/tools/bench_pipeline.py", "pipeline_vs_solve", "handeye.app.engine.request"),
        ("app/tools/bench_pipeline.py", "pipeline_vs_solve", "handeye.app.public.api"),
        ("app/tools/bench_solvers.py", "_calibration_starts", "handeye.model.chain.pose"),
        ("app/tools/bench_solvers.py", "_calibration_starts", "handeye.model.common.rotation"),
        ("app/tools/bench_solvers.py", "_calibration_starts", "handeye.model.fit.calibration"),
        ("app/tools/bench_solvers.py", "_calibration_starts", "handeye.model.simulation.simulate"),
        ("app/tools/bench_solvers.py", "calibration", "handeye.model.compiled.fast"),
        ("app/tools/sweep.py", "_worker_end", "handeye.model.common.scratch"),
        ("model/datasets/dataset.py", "_centre_from_profile", "handeye.model.geometry.circle"),
        ("model/datasets/dataset.py", "_check_truth_params", "handeye.model.robot.robot_errors"),
        ("model/datasets/dataset.py", "_clean_profile", "handeye.model.geometry.profile_clean"),
        ("model/datasets/dataset.py", "_set_aside", "handeye.model.datasets.arcs"),
        ("model/design/bounds.py", "information", "handeye.model.simulation.simulate"),
        ("model/design/identifiability.py", "plate_pose_analysis", "handeye.model.fit.calibration"),
        ("model/design/identifiability.py", "structural", "handeye.model.fit.calibration"),
        ("model/design/planning.py", "cell_candidates", "handeye.model.simulation.simulate_mounts"),
        ("model/design/planning.py", "cell_information", "handeye.model.fit.cell"),
        ("model/fit/calibration.py", "nlp", "handeye.model.fit.nlp_problem"),
        ("model/fit/extended.py", "robot_motion", "handeye.model.chain.mounts"),
        ("model/fit/extended.py", "robot_motion", "handeye.model.robot.robot_errors"),
        ("model/fit/nlp_problem.py", "nlp", "handeye.model.fit.nlp_callback"),
        ("model/geometry/circle.py", "geometric", "handeye.solvers"),
        ("model/robot/robots.py", "offset_derivatives", "handeye.model.robot.robot_errors"),
        ("model/simulation/simulate.py", "_robot_section", "handeye.model.robot.robots"),
        ("model/simulation/simulate.py", "robot_errors", "handeye.model.robot.robot_errors"),
        ("model/simulation/simulate.py", "write", "handeye.model.chain.conventions"),
        ("studies/study_classics.py", "_real_data", "handeye.app.engine.robust"),
        ("studies/study_classics.py", "_real_data", "handeye.app.tools.bench"),
        ("studies/study_default.py", "one", "handeye.model.chain.conventions"),
    ],
    "start-up: would load joblib at import, which the module does not load yet": [
        ("app/tools/sweep.py", "run", "joblib"),
    ],
    "start-up: would load matplotlib at import, which the module does not load yet": [
        ("app/present/figure_style.py", "_colour_ok", "matplotlib.colors"),
        ("app/present/figure_style.py", "_mappables", "matplotlib.cm"),
        ("app/present/figure_style.py", "_off_palette", "matplotlib.collections"),
        ("app/present/figure_style.py", "_off_palette", "matplotlib.colors"),
        ("app/present/figure_style.py", "_off_palette", "matplotlib.lines"),
        ("app/present/figure_style.py", "_off_palette", "matplotlib.patches"),
        ("app/present/figure_style.py", "_points", "matplotlib.collections"),
        ("app/present/figure_style.py", "_points", "matplotlib.container"),
        ("app/present/figure_style.py", "_points", "matplotlib.lines"),
        ("app/present/figure_style.py", "_small_text", "matplotlib.text"),
        ("app/present/figure_style.py", "apply", "matplotlib"),
        ("app/present/figure_style.py", "style", "matplotlib"),
        ("app/present/plotting.py", "figure", "matplotlib"),
        ("app/present/plotting.py", "figure", "matplotlib.pyplot"),
        ("app/present/web/figures.py", "new_figure", "matplotlib.figure"),
        ("studies/study.py", "save", "matplotlib.pyplot"),
        ("studies/study_testfunction.py", "_draw", "matplotlib.colors"),
        ("studies/study_testfunction.py", "_draw", "matplotlib.patches"),
    ],
    "start-up: would load mpl_toolkits at import, which the module does not load yet": [
        ("studies/study_mounts.py", "_fan", "mpl_toolkits.mplot3d.art3d"),
    ],
    "start-up: would load numpy at import, which the module does not load yet": [
        ("app/present/interactive.py", "png_from_figure", "handeye.app.present.figure_style"),
        ("app/present/plotting.py", "figure", "handeye.app.present.figure_style"),
    ],
    "start-up: would load sympy at import, which the module does not load yet": [
        ("app/engine/problems.py", "testfunction_nlp", "handeye.model.chain.codegen"),
        ("app/engine/problems.py", "testfunction_nlp", "handeye.model.chain.symbolic"),
        ("model/chain/codegen.py", "_print_function", "sympy"),
        ("model/chain/conventions.py", "build", "handeye.model.chain.symbolic"),
        ("model/chain/pose.py", "build", "handeye.model.chain.symbolic"),
        ("model/chain/testfunction.py", "build", "handeye.model.chain.symbolic"),
        ("model/chain/testfunction.py", "stationary_points", "sympy"),
        ("model/design/identifiability.py", "plate_pose_analysis", "handeye.model.chain.codegen"),
        ("model/design/identifiability.py", "plate_pose_analysis", "handeye.model.chain.symbolic"),
        ("model/effects/__init__.py", "build", "sympy"),
        ("model/effects/sensor_scale.py", "correction", "sympy"),
        ("model/effects/sphere_radius.py", "correction", "sympy"),
        ("model/fit/calibration.py", "build", "handeye.model.chain.symbolic"),
        ("model/fit/cell.py", "build", "handeye.model.chain.symbolic"),
        ("model/fit/classics.py", "build", "handeye.model.chain.symbolic"),
    ],
    "the module looks for it in sys.modules (used only when something else loaded it)": [
        ("app/command/cli.py", "_stop_workers", "multiprocessing"),
    ],
}

def _room(path):
    """(layer, room) of a module's file; room '' is the layer's own __init__.py."""
    parts = path.relative_to(ROOT).parts
    return parts[0], ".".join(parts[1:-1])


def test_every_module_lives_in_a_room():
    for layer in ROOMS:
        for path in sorted((ROOT / layer).rglob("*.py")):
            lay, room = _room(path)
            if room == "":
                assert path.name == "__init__.py", f"{path.relative_to(ROOT)}: loose in {layer}/, put it in a room"
            else:
                assert room in ROOMS[layer], f"{path.relative_to(ROOT)}: room {room!r} is not in ROOMS"


def test_rooms_import_one_way():
    """Within a layer, a room imports only the rooms ROOMS lets it (module level and in functions)."""
    modules = {_module_name(p): p for p in _modules()}
    for name, deps in _import_graph().items():
        lay, room = _room(modules[name]) if modules[name].parent != ROOT else (None, None)
        if lay not in ROOMS:
            continue
        for dep in deps:
            dlay, droom = _room(modules[dep]) if modules[dep].parent != ROOT else (None, None)
            if dlay != lay or droom in ("", room):
                continue
            assert droom in ROOMS[lay].get(room, ()), (
                f"{modules[name].relative_to(ROOT)} imports {dep}: room {room!r} may not import room {droom!r}")


def test_the_rooms_have_no_cycle():
    for layer, rooms in ROOMS.items():
        assert _cycles({r: set(d) for r, d in rooms.items()}) == [], layer


def _function_imports(tree, modules):
    """(function, module) of every import inside a function body; ``from a import b`` imports the
    module ``a.b`` when that is one of handeye's modules, else ``a``."""
    found = []

    def visit(node, function):
        for child in ast.iter_child_nodes(node):
            name = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) else function
            if function is not None and isinstance(child, ast.Import):
                found.extend((function, a.name) for a in child.names)
            elif function is not None and isinstance(child, ast.ImportFrom):
                subs = [f"{child.module}.{a.name}" for a in child.names]
                found.extend((function, sub if sub in modules else child.module) for sub in subs)
            visit(child, name)

    visit(tree, None)
    return found


def test_function_level_imports_are_listed_with_their_reason():
    """An import sits at module level unless LOCAL_IMPORTS gives it a reason; the list has no stale entry."""
    listed = {entry: reason for reason, entries in LOCAL_IMPORTS.items() for entry in entries}
    found = set()
    modules = {_module_name(p) for p in _modules()}
    for path in _modules():
        rel = path.relative_to(ROOT).as_posix()
        for fn, name in _function_imports(ast.parse(path.read_text(), rel), modules):
            found.add((rel, fn, name))
    assert not sorted(found - set(listed)), (
        f"imports inside functions without a reason in LOCAL_IMPORTS (hoist them): {sorted(found - set(listed))}")
    assert not sorted(set(listed) - found), f"LOCAL_IMPORTS lists imports that are gone: {sorted(set(listed) - found)}"


# --- end of rooms and local imports ---
