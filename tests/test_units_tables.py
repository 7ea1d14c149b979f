"""Every table column and every console number of the reports carries its unit, and the right one:
V (not N) for the force levels of a run whose force gain is unknown, k3/m (not k3 in N/m³) for its
stiffness, Hz for frequencies and rad/s for angular frequencies.

The reports are parsed as HTML (html.parser), not matched as markup: each table's header cells
are read and checked, and so is each row of a table that has a ``unit`` column."""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser

import pytest

from jointid.app.synthesis import load_simulation_config, simulate_campaign
from jointid.cli import main

CONFIG = {
    "campaign": {"name": "units test"},
    "model": [{"preload": 120, "terms": "q + -q^3 + q'", "omega1": 170.0, "coefficients": {"k3": 5e6},
               "amplitude_laws": {"c": [0.08, 70.0, 1e4]}}],
    "excitation": {"force_levels": [0.5, 1.0], "omega_start": 160.0, "omega_stop": 180.0, "n_frequencies": 10},
    "acquisition": {"fs": 2000.0, "periods": 20.0, "noise": 0.01, "seed": 3, "n_harmonics": 7},
}

#: Headers that name things, not quantities (labels, counts, verdicts, texts): no unit.
LABELS = {
    "preload", "model", "quantity", "value ± standard error", "95 % interval", "unit", "note", "verdict", "what",
    "warning", "warnings", "example", "records", "error", "file", "status", "index", "check", "value", "passed", "stage",
    "setting", "terms", "rule", "selected model", "coefficient", "fit", "band average", "reference", "folder",
    "manifest names", "formats", "failed", "UFF = CSV", "in [2, 3]", "n within [2, 3]", "parameters", "other",
    "peak resolved by the dwells", "outlier records", "parameter", "equality across force levels", "campaigns",
    "grid point", "grid_point", "n", "n (missing)", "details", "kind", "source", "data set", "name", "set", "method",
    "test set", "choice",
}
UNIT = re.compile(r"\[([^\]]+)\]")


class Tables(HTMLParser):
    """The tables of a page: ``[{"caption", "headers", "rows"}]`` (cell texts)."""

    def __init__(self):
        super().__init__()
        self.tables, self._t, self._row, self._cell, self._cap = [], None, None, None, None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self._t = {"caption": "", "headers": [], "rows": []}
        elif tag == "caption" and self._t is not None:
            self._cap = []
        elif tag == "tr" and self._t is not None:
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "table" and self._t is not None:
            self.tables.append(self._t)
            self._t = None
        elif tag == "caption" and self._cap is not None:
            self._t["caption"], self._cap = "".join(self._cap).strip(), None
        elif tag in ("td", "th") and self._cell is not None:
            self._row.append(("th" if tag == "th" else "td", "".join(self._cell).strip()))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            if self._row and all(k == "th" for k, _ in self._row):
                self._t["headers"] = [v for _, v in self._row]
            elif self._row:
                self._t["rows"].append([v for _, v in self._row])
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)
        elif self._cap is not None:
            self._cap.append(data)


def tables_of(path):
    p = Tables()
    p.feed(path.read_text(encoding="utf-8"))
    assert p.tables, f"{path}: no table"
    return p.tables


def _unit(header):
    m = UNIT.search(header)
    return m.group(1) if m else None


def check_header(header, gain_free, where):
    """A header is a label or carries a unit in brackets, and the right one for what it names."""
    unit = _unit(header)
    name = UNIT.sub("", header).strip().lower()
    if unit is None:
        assert header in LABELS or header.lower() in LABELS, f"{where}: column {header!r} has no unit"
        return
    if unit in ("%", "1", "× noise"):  # relative errors, ratios, exponents: dimensionless, whatever they compare
        return
    first = name.split()[0] if name.split() else ""
    if first == "f" and header.startswith("F "):  # a force level (upper case F)
        assert unit == ("V" if gain_free else "N"), f"{where}: force level column {header!r}"
    if re.search(r"\bomega", name) and "omega1^2" not in name and "²" not in unit:
        assert unit == "rad/s", f"{where}: {header!r} is an angular frequency: rad/s"
    if re.search(r"(^|\s)(f1|f|peak f|frequency|folds)(\s|$)", name) and not header.startswith("F "):
        assert unit == "Hz", f"{where}: {header!r} is a frequency: Hz"
    if re.search(r"\bk3\b(?!/k)", name) and "joint" not in name and "raw" not in name:
        if gain_free or "k3/m" in name:  # a ratio to the inertia coefficient m = 1/g: per unit modal mass
            assert "k3/m" in name and unit == "1/(m² s²)", f"{where}: {header!r} must be k3/m [1/(m² s²)]"
        else:
            assert unit == "N/m³", f"{where}: {header!r}"
    if re.fullmatch(r"c\d?(/m)?( pooled)?", name):
        assert "/m" in name or not gain_free, f"{where}: {header!r} must be a ratio c/m in a gain-free run"
        assert (unit.startswith("1/") if "/m" in name else unit.startswith("N s/m")), f"{where}: {header!r}"


#: Unit of a quantity named in a table with a ``unit`` column (None: anything but empty).
ROW_UNITS = {"f1": "Hz", "omega1": "rad/s", "k3": "N/m³", "k3/m": "1/(m² s²)", "c0": "N s/m", "c1": "N s/m²",
             "c2": "N s/m³", "c0/m": "1/s", "c1/m": "1/(m s)", "c2/m": "1/(m² s)", "q_max range": "m"}


def check_page(path, gain_free=False):
    for t in tables_of(path):
        where = f"{path.parent.name}/{path.name}: table {t['caption'][:60]!r}"
        for h in t["headers"]:
            check_header(h, gain_free, where)
        if "unit" in t["headers"]:
            iu = t["headers"].index("unit")
            iq = next((t["headers"].index(k) for k in ("quantity", "coefficient", "parameter") if k in t["headers"]),
                      None)
            for row in t["rows"]:
                if iq is None or len(row) <= iu or row[iq] in ("model", "–"):
                    continue
                q = re.sub(r" \(at zero amplitude\)$", "", row[iq])
                if q in ("c1", "c2") and row[iu].startswith("N s/m^"):  # c1 q_max^p: the fitted power
                    continue
                if q in ROW_UNITS:
                    assert row[iu] == ROW_UNITS[q], f"{where}: {q} in {row[iu]!r}, expected {ROW_UNITS[q]}"
                elif not row[1:] or "not identified" not in " ".join(row):
                    assert row[iu], f"{where}: {q} without a unit"
                if gain_free:
                    assert q not in ("k3", "c0", "c1", "c2"), f"{where}: {q} in a gain-free run (ratios to m)"


#: ``name = value unit`` in the console: the unit that must follow each name's value.
CONSOLE = {"f1": "Hz", "omega1": "rad/s", "k3": "N/m³", "k3/m": "1/(m² s²)", "c0": "N s/m", "c0/m": "1/s",
           "c1/m": "1/(m s)", "c2/m": "1/(m² s)", "g": "N/V"}


def check_console(text, gain_free=False):
    for line in text.splitlines():
        for name, unit in CONSOLE.items():
            for m in re.finditer(rf"(?<![\w/^]){re.escape(name)}(?: \(at zero amplitude\))? = ([^,;]*?)(?:  |,|;|$)",
                                 line):
                value = m.group(1)
                if "not identified" in value:
                    continue
                assert value.rstrip().endswith(unit), f"console: {name} = {value!r} without {unit}: {line!r}"
        for m in re.finditer(r"\bF = (\S+) (\S+?):", line):
            assert m.group(2) == ("V" if gain_free else "N"), f"console: force level {m.group(0)!r}: {line!r}"
        if gain_free:
            assert not re.search(r"(?<![\w/])k3 = ", line), f"console: k3 in a gain-free run: {line!r}"
            assert "N/m³" not in line, f"console: N/m³ in a gain-free run: {line!r}"
        assert not re.search(r"omega1\^2 = [-+\d.()e± ]+$", line), f"console: omega1^2 without a unit: {line!r}"


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    return simulate_campaign(load_simulation_config(CONFIG), tmp_path_factory.mktemp("units") / "campaign")


@pytest.fixture(scope="module")
def identified(campaign, tmp_path_factory):
    """``identify`` with a known and with an unknown force gain: ``{gain: (folder, console)}``."""
    import contextlib
    import io

    out = {}
    for gain in ("known", "unknown"):
        folder = tmp_path_factory.mktemp("units") / f"out-{gain}"
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            main(["identify", str(campaign), "--out", str(folder), "--no-figures", "--force-gain", gain])
        out[gain] = (folder, buf.getvalue())
    return out


def test_identify_report_tables_carry_units(identified):
    check_page(identified["known"][0] / "report.html")


def test_identify_console_carries_units(identified):
    text = identified["known"][1]
    assert "k3 = " in text and "N/m³" in text and "F = 0.5 N" in text
    check_console(text)


def test_gain_free_run_is_in_volts_and_ratios_to_the_inertia(identified):
    folder, text = identified["unknown"]
    check_page(folder / "report.html", gain_free=True)
    check_console(text, gain_free=True)
    assert "k3/m = " in text and "F = 0.5 V" in text
    # the identified gain with its standard error and 95 % interval, in the console and the report
    groups = json.loads((folder / "results.json").read_text())["groups"]
    assert all(g.get("force_gain_stderr") for g in groups)
    assert len(re.findall(r"g = [\d.]+ ± [\d.]+ N/V  95 % \[", text)) == len(groups)
    gain = [t for t in tables_of(folder / "report.html") if t["caption"].startswith("Identified force gain")]
    assert gain and len(gain[0]["rows"]) == len(groups)
    assert "force gain g ± standard error [N/V]" in gain[0]["headers"] and "95 % interval [N/V]" in gain[0]["headers"]


def test_checker_catches_wrong_units():
    with pytest.raises(AssertionError):
        check_header("F [N]", True, "gain-free")
    with pytest.raises(AssertionError):
        check_header("k3 [N/m³] (pooled)", True, "gain-free")
    with pytest.raises(AssertionError):
        check_header("omega1 [Hz]", False, "x")
    with pytest.raises(AssertionError):
        check_header("f1 [rad/s]", False, "x")
    with pytest.raises(AssertionError):
        check_header("q_max", False, "x")
    with pytest.raises(AssertionError):
        check_console("  preload 1: k3 = (5.0 ± 0.1)e6  95 % [4.8, 5.2]e6")
    with pytest.raises(AssertionError):
        check_console("  preload 1, F = 0.5 N: 3 x warning", gain_free=True)
    check_header("k3/m [1/(m² s²)] (pooled)", True, "gain-free")
    check_console("  preload 1: k3/m = (5.0 ± 0.1)e6 1/(m² s²)  95 % [4.8, 5.2]e6", gain_free=True)


def test_example_report_and_console_carry_units(tmp_path, capsys):
    main(["example", "--out", str(tmp_path / "ex"), "--frequencies", "11", "--no-figures", "--quiet"])
    text = capsys.readouterr().out
    check_page(tmp_path / "ex" / "eq21" / "report.html")
    check_console(text)
    values = {"exact", "band average", "identified", "paper identified", "pooled ± standard error",
              "identified ± standard error"}
    for table in text.split("Table ")[1:]:
        lines = table.strip().splitlines()
        header = re.split(r"\s{2,}", lines[1].strip())
        assert header[0] == "parameter", header  # the unit is on each row's parameter
        for name in header[1:]:
            if name not in values:
                check_header(name, False, "example console")
        for line in lines[3:]:
            if not line.strip():
                break
            check_header(re.split(r"\s{2,}", line.strip())[0], False, "example console")
    assert "omega1 [rad/s]" in text and "k3 [N/m³]" in text and "c2 [N s/m³]" in text


def test_study_report_tables_carry_units(tmp_path):
    plan = tmp_path / "plan.toml"
    plan.write_text("""
[study]
name = "units"
campaigns = 2
seed = 5
[[model]]
omega1 = 170.0
coefficients = { k3 = 5e6, c = 0.5 }
[excitation]
force_levels = [1.0]
omega_start = 162.0
omega_stop = 178.0
n_frequencies = 5
[acquisition]
fs = 1500.0
periods = 8
noise = 0.01
""")
    main(["study", str(plan), "--out", str(tmp_path / "out"), "--quiet"])
    check_page(tmp_path / "out" / "report.html")


@pytest.mark.slow
def test_demo_report_and_console_carry_units(demo_run):
    text = demo_run.report()  # what `jointid demo` prints
    out = demo_run.out_dir
    check_page(out / "report.html")
    check_console(text)
    assert "Selected model: micro-slip + cubic" in text or "Selected model:" in text
    # the report's Table 5 band average of each preload is that preload's own (results.json)
    from jointid.report.formatting import format_pm
    from jointid.report.summary import band_resolution

    tables = tables_of(out / "report.html")
    assert "the model the data select" in tables[0]["caption"]
    (t5,) = [t for t in tables if t["caption"].startswith("The paper's Table 5")]
    col = t5["headers"].index("k3 [N/m³] band average (paper)")
    shown = {(r[0], r[1]): r[col] for r in t5["rows"]}
    demo = json.loads((out / "results.json").read_text())
    for pr in demo["preloads"]:
        s = pr["identification"]
        for g in s["groups"]:
            band = band_resolution(s, g)
            assert band["mean"] == pytest.approx(g["k3_mean"], rel=1e-12)
            assert shown[(str(g["preload"]), f"{g['force_level']:g}")] == format_pm(g["k3_mean"], band["stderr"])
    assert len(set(shown.values())) == len(shown)  # 120 N and 540 N differ


def test_backbone_console_carries_units(identified, tmp_path, capsys):
    folder, _ = identified["known"]
    main(["backbone", str(folder / "results.json"), "--out", str(tmp_path / "bb")])
    text = capsys.readouterr().out
    headers = [re.split(r"\s{2,}", line.strip()) for line in text.splitlines() if "a [m]" in line]
    assert headers, text[:500]
    for header in headers:
        assert header == ["a [m]", "f ± standard error [Hz]", "zeta ± standard error [%]"]
        for h in header:
            check_header(h, False, "backbone console")


def test_modal_console_carries_units(tmp_path, capsys):
    (tmp_path / "s.toml").write_text('[structure]\nmodel = "seed-bolted-beam"\npreload = 120\n'
                                     '[structure.sensors]\naccel_42 = 0.42\n')
    main(["modal", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o")])
    text = capsys.readouterr().out
    assert re.search(r"FE frequencies \[Hz\]: 26\.4", text), text
    assert re.search(r"at x = 0\.42 m: phi = [\d.]+ 1/√kg", text), text


@pytest.mark.slow
def test_public_data_report_tables_carry_units(tmp_path, shared_data, capsys):
    main(["public-data", "--out", str(tmp_path / "pub")])
    check_page(tmp_path / "pub" / "report.html")
    check_console(capsys.readouterr().out)
