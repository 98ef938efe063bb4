import numpy as np
import pandas as pd

from neurender import io, methods
from neurender.deployment import deployment_row, deployment_table
from neurender.report import build as report


def test_report_shows_measurements_and_marks_unrun_sections(tmp_path):
    res = tmp_path / "results" / "prt"
    df = pd.DataFrame(
        {
            "method": ["prt"] * 2,
            "dataset": ["head"] * 2,
            "model": ["DeepPRT"] * 2,
            "split": ["test"] * 2,
            "metric": ["ssim", "ssim"],
            "value": [0.5, 0.7],
        }
    )
    io.write_csv(res / "metrics.csv", df)
    io.write_png(res / "figures" / "example.png", np.full((4, 4, 3), 255, np.uint8))
    out = tmp_path / "report.html"
    report.build_report([res / "metrics.csv"], [res / "figures" / "example.png"], out)
    html = out.read_text()
    # The table shows the mean of the two frames (0.5, 0.7), not either frame.
    assert "<td>0.6</td>" in html and "<td>0.5</td>" not in html and "<td>0.7</td>" not in html
    assert "data:image/png;base64," in html
    assert html.count("has not been run") == 3  # ndr, metaballs, simplification
    assert "44.47" in html  # the paper's compression ratio stands beside ours


def test_paper_numbers_are_tidy():
    p = report.paper_numbers()
    assert {"method", "source", "metric", "value"} <= set(p.columns)
    assert set(p.method) <= {m.key for m in methods.METHODS}


def test_a_section_with_data_but_no_metrics_says_so(tmp_path):
    res = tmp_path / "results" / "metaballs"
    df = pd.DataFrame(
        {
            "method": ["metaballs"],
            "dataset": ["examples"],
            "model": ["ray marcher"],
            "split": ["train"],
            "metric": ["examples"],
            "value": [10.0],
        }
    )
    io.write_csv(res / "data.csv", df)
    report.build_report([res / "data.csv"], [], tmp_path / "r.html")
    html = (tmp_path / "r.html").read_text()
    assert "Only the data stage of this method has run" in html
    assert html.count("has not been run") == 3


def test_table_cells_are_escaped(tmp_path):
    res = tmp_path / "results" / "metaballs"
    io.write_csv(
        res / "targets.csv", pd.DataFrame({"check": ["error <= 15 deg & <b>"], "met": [True]})
    )
    report.build_report([res / "targets.csv"], [], tmp_path / "r.html")
    assert "error &lt;= 15 deg &amp; &lt;b&gt;" in (tmp_path / "r.html").read_text()


def test_table_headers_are_escaped(tmp_path):
    res = tmp_path / "results" / "metaballs"
    script = "<script>alert(1)</script>"
    io.write_csv(res / "data.csv", pd.DataFrame({script: ["a"], "x & y": [1.0]}))
    tidy = pd.DataFrame(  # a tidy table: metric names become the pivoted table's headers
        {
            "method": ["metaballs"],
            "dataset": ["d"],
            "model": ["m"],
            "split": ["test"],
            "metric": [script],
            "value": [0.5],
        }
    )
    io.write_csv(res / "metrics.csv", tidy)
    report.build_report([res / "data.csv", res / "metrics.csv"], [], tmp_path / "r.html")
    page = (tmp_path / "r.html").read_text()
    assert "<script>alert" not in page
    assert page.count("<th>&lt;script&gt;alert(1)&lt;/script&gt;</th>") == 2
    assert "<th>x &amp; y</th>" in page


def _tidy(rows):
    return pd.DataFrame(
        [("ndr", "complex", m, "test", metric, v) for m, metric, v in rows],
        columns=["method", "dataset", "model", "split", "metric", "value"],
    )


def test_training_budget_says_equal_only_when_every_model_had_the_same_epochs():
    equal = _tidy([("ndr", "epochs", 8), ("pix2pix", "epochs", 8), ("ndr", "dssim", 0.1)])
    assert "equal, 8 epochs" in report.training_budget(equal)
    assert "ndr, pix2pix" in report.training_budget(equal)
    unequal = _tidy([("ndr", "epochs", 8), ("pix2pix", "epochs", 2)])
    assert report.training_budget(unequal) == (
        "Training budget: unequal, epochs per learned model: ndr 8; pix2pix 2."
    )
    per_material = _tidy([("DeepPRT", "epochs_diffuse", 12), ("DeepPRT", "epochs_glossy", 10)])
    assert "unequal" in report.training_budget(per_material)
    assert report.training_budget(_tidy([("ndr", "dssim", 0.1)])) == ""


def _deployment(path, method: str, networks: list[str], ms: float) -> None:
    rows = []
    for n in networks:
        onnx_file = path.parent / f"{n}.onnx"
        onnx_file.parent.mkdir(parents=True, exist_ok=True)
        onnx_file.write_bytes(bytes(52_000))
        times = {"onnxruntime": ms, "pytorch": 2 * ms}
        rows.append(
            deployment_row(
                method, n, onnx_file, (64, 64), 12345, 2e-7, times, 2, "Test CPU, 2 threads"
            )
        )
    io.write_csv(path, deployment_table(rows))


def test_the_summary_sets_every_deployed_network_beside_the_papers_times(tmp_path):
    tables = [tmp_path / "results" / m / "deployment.csv" for m in ("ndr", "prt")]
    _deployment(tables[0], "ndr", ["ndr", "pix2pix"], 3.25)
    _deployment(tables[1], "prt", ["head diffuse", "head glossy"], 1.5)
    report.build_report(tables, [], tmp_path / "r.html")
    page = (tmp_path / "r.html").read_text()
    summary = page[page.index('id="deployment"') : page.index('<h2 id="prt">')]
    ours = summary[: summary.index("The papers' network times")]
    papers = summary[summary.index("The papers' network times") :]
    # One row per network, methods in report order (DeepPRT first), both engines' times.
    assert ours.index("head diffuse") < ours.index("head glossy") < ours.index(">pix2pix<")
    assert ours.count("</tr>") == 1 + 4
    for value in ("1.5", "3", "3.25", "6.5", "12,345", "52 kB", "2e-07", "64x64"):
        assert f"<td>{value}</td>" in ours
    assert "<strong>Test CPU, 2 threads</strong>" in ours
    # each engine's column holds its times: ONNX Runtime 1.5 ms, PyTorch twice that
    assert ours.index("ONNX Runtime ms") < ours.index("PyTorch ms")
    row = ours[ours.index("head diffuse") :].split("</tr>", 1)[0]
    assert row.index("<td>1.5</td>") < row.index("<td>3</td>")
    # Beside them the published times with their hardware; no metaballs row (not deployed).
    assert papers.count("</tr>") == 1 + 2
    assert "<td>45</td>" in papers and "NVIDIA RTX 2080" in papers
    assert "<td>6</td>" in papers and "hardware not stated" in papers
    assert "<td>11,800,000</td>" in papers and "not stated</td>" in papers
    assert "GTX 1080" not in papers


def test_no_deployment_table_without_deployed_networks(tmp_path):
    report.build_report([], [], tmp_path / "r.html")
    assert 'id="deployment"' not in (tmp_path / "r.html").read_text()


def test_the_report_names_the_commit_and_holds_the_provenance_collapsed(tmp_path):
    from neurender import provenance
    from neurender.report.jobs import commit_label

    record = provenance.collect({"seed": 7}, ["config/smoke.yaml"], tmp_path, tmp_path / "s")
    record["git"] = {"commit": "0123456789abcdef" * 2 + "01234567", "dirty": True}
    label = commit_label(record["git"])
    assert label == "0123456789ab + uncommitted changes"
    assert commit_label({"commit": None, "dirty": None}) == "not a git checkout"
    out = tmp_path / "r.html"
    report.build_report([], [], out, run_info={"commit": label}, provenance=record)
    html = out.read_text()
    header, _, rest = html.partition('<details id="provenance">')
    assert "commit: <code>0123456789ab + uncommitted changes</code>" in header
    assert record["git"]["commit"] in rest and "with uncommitted changes" in rest
    assert f"<th>torch</th><td>{record['packages']['torch']}</td>" in rest
    assert "&#34;seed&#34;: 7" in rest or '"seed": 7' in rest
    report.build_report([], [], out)
    assert 'id="provenance"' not in out.read_text()


def test_tables_with_one_stem_in_two_folders_each_show_their_own_rows(tmp_path):
    # DeepPRT's experiments: results/prt/<experiment>/experiment.csv, one stem for all.
    res = tmp_path / "results" / "prt"
    tables = []
    for experiment, value in (("head_linear", 0.125), ("head_excluded", 0.875)):
        rows = {"method": "prt", "dataset": "head", "model": "DeepPRT", "split": "test"}
        frame = pd.DataFrame([{**rows, "metric": "relative_l1", "value": value}])
        io.write_csv(res / experiment / "experiment.csv", frame)
        tables.append(res / experiment / "experiment.csv")
    report.build_report(tables, [], tmp_path / "r.html")
    html = (tmp_path / "r.html").read_text()
    # each table's block runs from its file's name to the next heading
    linear = html.split("head_linear/experiment.csv", 1)[1].split("<h3>", 1)[0]
    excluded = html.split("head_excluded/experiment.csv", 1)[1].split("<h3>", 1)[0]
    assert "<td>0.125</td>" in linear and "<td>0.875</td>" not in linear
    assert "<td>0.875</td>" in excluded and "<td>0.125</td>" not in excluded
    assert "<h3>head linear/experiment</h3>" in html
    assert "<h3>head excluded/experiment</h3>" in html
