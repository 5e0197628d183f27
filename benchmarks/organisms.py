"""Real animals: tracked fish and a crawling worm through `suds import` and `suds identify`, against kernel ridge.

Data (not in this repository).  Two fish, the example recordings of the R package fishmechr (Eric
Tytell, Tufts University; https://github.com/tytell/fishmechr, licence CC BY 4.0), files under its
``data-raw/``:

zebrafish   ``2024-11-14_labels2.001_fish_01-040RPM-ortho-….analysis.csv``: an adult zebrafish
            (*Danio rerio*) in a flow tank at 40 RPM, SLEAP keypoints seen from below, 250 frames
            at 50 fps (the package's vignette ``process_sleap_data``: fps 50, good frames 1–250).
prickleback ``XMUC02_Trial1_sleap-1.csv``: a rock prickleback (*Xiphister mucosus*, an eel-like
            fish), SLEAP keypoints Snout, BP1–BP6, Tail, 711 frames at 60 fps (vignette
            ``prickleback_swimming``: t = frame_idx / 60).

Get them with ``git clone https://github.com/tytell/fishmechr`` (measured at commit 6655ac9) and pass
the checkout, or a bare mirror of it, as ``--fishmechr PATH`` (default ``benchmarks/data/fishmechr``).

One crawling nematode, the example file of OpenWorm's movement_cloud (https://github.com/openworm/movement_cloud,
licence MIT, ``LICENSE.md``):

worm        ``webworm/static/webworm/example.wcon``: a *C. elegans* adult hermaphrodite (strain RB1374,
            ocr-3(ok1559)) crawling off food on NGM agar, Schafer lab single-worm tracker (MRC LMB,
            2010), exported by Tierpsy to WCON: 49-point skeletons in plate coordinates (µm), 25 fps,
            820 frames, 41 % of them lost by the tracker.  Imported from the WCON file as it is.

Get it with ``git clone https://github.com/openworm/movement_cloud`` (measured at commit 5af05a2) and
pass the checkout, or a bare mirror, as ``--movement-cloud PATH`` (default
``benchmarks/data/movement_cloud``).

For each fish the keypoints are written as a midline CSV (head first, pixels; a missing point
leaves the frame lost, which `suds import` drops and reports); the worm's WCON file is imported
directly.  Each recording is imported with ``suds import``,
identified with ``suds identify --model`` on the first cycles (12 of the zebrafish's, 3 of the
prickleback's, 9 of the worm's) and scored on every later one (held-out cycles), and the same split is given to
the kernel-ridge peer of ``benchmarks/peers.py``
(RBF kernel ridge on the identifier's own interval inputs [r̄, ṙ_a, cos φ, sin φ], its
hyperparameters by blocked cross-validation on the training cycles).  Γ per body channel:
1 − Σ|prediction − measured| / Σ|phase-only template − measured| on the held-out intervals.
`suds identify` itself first brings a recording with absent frames onto a uniform grid and then
scores the body velocity over the pose stream's own intervals; the per-channel comparison here
fits the same identifier without that step (``IdentifyConfig(regrid=False)``: intervals between
the file's frames, one set of intervals for both methods), and the report gives both.
The fish files state no pixel size: lengths are imported with a nominal 0.1 mm per pixel, which
changes no Γ (every output scales alike, the ridge is relative).

    PYTHONPATH=. python benchmarks/organisms.py [--fishmechr PATH] [--movement-cloud PATH]

Needs scikit-learn (benchmarks/requirements-peers.txt) and matplotlib.  Writes
docs/results/organisms.md and docs/results/organisms.png.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import csv  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from _common import ROOT, RESULTS, machine, stamp, write  # noqa: E402

from suds_ros.cli.main import main as suds  # noqa: E402
from suds_ros.report.diagnosis import parameter_text  # noqa: E402

SOURCES = {  # data set → (where it is fetched from, default local path, licence)
    "fishmechr": ("https://github.com/tytell/fishmechr", ROOT / "benchmarks" / "data" / "fishmechr",
                  "CC BY 4.0"),
    "movement_cloud": ("https://github.com/openworm/movement_cloud",
                       ROOT / "benchmarks" / "data" / "movement_cloud", "MIT"),
}
PX = 1e-4  # nominal metres per pixel (the files give none; Γ does not depend on it)


@dataclass(frozen=True)
class Animal:
    """One tracked recording and how it is read."""

    name: str
    species: str
    source: str  # key of SOURCES
    file: str
    fps: float | None  # None: the file has times (WCON)
    points: tuple[tuple[str, ...], ...] | None  # SLEAP keypoints head to tail (several: their mean); None: WCON
    links: int
    train: int  # training cycles (the rest is held out)
    note: str


ANIMALS = (
    Animal("zebrafish", "Danio rerio (adult), flow tank 40 RPM", "fishmechr",
           "data-raw/2024-11-14_labels2.001_fish_01-040RPM-ortho-2024-11-14T044525.analysis.csv", 50.0,
           (("snout",), ("left_eye", "right_eye"), ("left_pec_fin_base", "right_pec_fin_base"),
            ("pelvic_fin_base",), ("anus",), ("peduncle",)),
           4, 12, "SLEAP keypoints from below; midline: snout, eye centre, pectoral-fin-base centre, pelvic "
                  "fin base, anus, peduncle (the caudal-fin lobes are missing in a third of the frames)"),
    Animal("prickleback", "Xiphister mucosus (rock prickleback)", "fishmechr", "data-raw/XMUC02_Trial1_sleap-1.csv",
           60.0, (("Snout",), ("BP1",), ("BP2",), ("BP3",), ("BP4",), ("BP5",), ("BP6",), ("Tail",)),
           7, 3, "SLEAP keypoints Snout, BP1–BP6, Tail (the keypoints are the joints)"),
    Animal("worm", "Caenorhabditis elegans (adult hermaphrodite, RB1374 ocr-3(ok1559)), crawling off food on agar",
           "movement_cloud", "webworm/static/webworm/example.wcon", None, None,
           8, 9, "Schafer lab single-worm tracker (2010), WCON exported by Tierpsy: 49-point skeletons in "
                 "plate coordinates, µm, 25 fps; crawling, so every joint is driven"),
)


def read_text(source: Path, path: str, key: str) -> str:
    """A file of a checkout (``source/path``) or of a bare git mirror (``HEAD:path``) of ``SOURCES[key]``."""
    if (source / path).is_file():
        return (source / path).read_text(encoding="utf-8-sig")
    if (source / "HEAD").is_file():
        out = subprocess.run(["git", f"--git-dir={source}", "show", f"HEAD:{path}"], capture_output=True)
        if out.returncode == 0:
            return out.stdout.decode("utf-8-sig")
    url, default, _ = SOURCES[key]
    raise SystemExit(f"{path} not found under {source}.\nGet the data with:\n  git clone {url} "
                     f"{default}\nor pass --{key.replace('_', '-')} PATH (a checkout or a bare mirror of {url}).")


def source_commit(source: Path) -> str:
    git = ["git", f"--git-dir={source}"] if (source / "HEAD").is_file() else ["git", "-C", str(source)]
    out = subprocess.run(git + ["rev-parse", "HEAD"], capture_output=True, text=True)
    return out.stdout.strip()[:12] if out.returncode == 0 else "unknown"


def midline_csv(animal: Animal, text: str, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Write the keypoints as a suds midline CSV (frame, x0, y0, … head first, px); returns frames, points."""
    rows = list(csv.DictReader(io.StringIO(text)))
    frames = np.array([int(float(r["frame_idx"])) for r in rows])

    def value(r: dict[str, str], key: str) -> float:
        v = r.get(key, "")
        return float(v) if v not in ("", None, "NA", "nan") else np.nan

    pts = np.array([[[np.mean([value(r, f"{n}.{c}") for n in names]) for c in "xy"] for names in animal.points]
                    for r in rows])
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["frame"] + [f"{c}{k}" for k in range(pts.shape[1]) for c in "xy"])
        for fr, p in zip(frames, pts):
            w.writerow([fr] + ["" if not np.isfinite(v) else f"{v:.4f}" for v in p.ravel()])
    return frames, pts


def run_cli(argv: list[str]) -> tuple[int, str]:
    """``suds argv``: exit code and what it printed (on failure, what it printed to stderr too)."""
    buf, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(err):
        rc = suds(argv)
    return rc, buf.getvalue() + (err.getvalue() if rc != 0 else "")


def gamma(pred: np.ndarray, truth: np.ndarray, template: np.ndarray) -> np.ndarray:
    """Γ per column: 1 − Σ|pred − truth| / Σ|template − truth|."""
    return 1.0 - np.abs(pred - truth).sum(0) / np.abs(template - truth).sum(0)


def one(animal: Animal, source: Path, work: Path) -> dict:
    from peers import data_of, groups_of, run_krr

    from suds_ros.cli.common import load_recording_and_model
    from suds_ros.core.ident.identify import IdentifyConfig, SudsIdentifier, split_cycles
    from suds_ros.io.tracks import read_tracks

    n_train = animal.train
    rec_path = work / f"{animal.name}.mcap"
    text = read_text(source, animal.file, animal.source)
    if animal.points is None:  # a WCON file, imported as it is
        src = work / f"{animal.name}.wcon"
        src.write_text(text, encoding="utf-8")
        tracks = read_tracks(src)
        frames, pts = np.arange(tracks.points.shape[0]), tracks.points
        flags = []
    else:
        src = work / f"{animal.name}.csv"
        frames, pts = midline_csv(animal, text, src)
        flags = ["--units", "px", "--px-size", repr(PX), "--fps", repr(animal.fps)]
    rc, text = run_cli(["import", str(src), "-o", str(rec_path), "--links", str(animal.links), *flags,
                        "--json", "--overwrite"])
    if rc != 0:
        raise SystemExit(f"suds import failed for {animal.name}")
    imp = json.loads(text)
    model_path = rec_path.with_suffix(".yaml")
    rc, text = run_cli(["identify", str(rec_path), "--model", str(model_path), "--train-cycles", str(n_train),
                        "--test-cycles", "1000", "--json"])
    if rc != 0:
        raise SystemExit(f"suds identify failed for {animal.name}")
    cli = json.loads(text)
    # the live estimator's algorithm on the same split (what the estimator node would publish)
    rc, text = run_cli(["identify", str(rec_path), "--model", str(model_path), "--train-cycles", str(n_train),
                        "--test-cycles", "1000", "--streaming", "--init-cycles", str(min(5, n_train)), "--json"])
    # too few cycles for the phaser is an answer (the error is reported), not a failed benchmark
    live = json.loads(text) if rc == 0 else {"error": (text.strip().splitlines() or ["(no message)"])[-1]}
    rc, text = run_cli(["diagnose", str(rec_path), "--model", str(model_path), "--json"])
    if rc != 0:
        raise SystemExit(f"suds diagnose failed for {animal.name}")
    diag = json.loads(text)

    # the same fit in-process, for per-channel Γ and the peer on identical inputs and split
    ns = argparse.Namespace(model=str(model_path), system=None, actuated=None, passive=None, gait_hz=None,
                            namespace="")
    rec, _ = load_recording_and_model(str(rec_path), ns)
    train, test = split_cycles(rec, n_train, 1000)
    # regrid=False keeps pose and shape on the file's own stamps (frames the file lacks stay gaps),
    # so every body channel is scored on the same intervals for both methods
    ident = SudsIdentifier(IdentifyConfig(regrid=False)).fit(train)
    pred = ident.predict(test)
    dtr, dte = data_of(ident, train, True), data_of(ident, test, False)
    assert np.allclose(dte.Y, pred.truth) and np.allclose(dte.T, pred.template)
    krr, _, krr_params = run_krr(dtr, dte, groups_of(pred.channels), 0)
    body = [i for i, c in enumerate(pred.channels) if c.startswith("xi_")]
    return {
        "animal": animal, "import": imp, "identify": cli, "streaming": live, "diagnose": diag,
        "channels": [pred.channels[i] for i in body],
        "gamma_ours": gamma(pred.model[:, body], pred.truth[:, body], pred.template[:, body]).tolist(),
        "gamma_krr": gamma(krr[:, body], pred.truth[:, body], pred.template[:, body]).tolist(),
        "krr_params": krr_params, "frames": frames, "pts": pts, "t": pred.t, "truth": pred.truth[:, body],
        "ours": pred.model[:, body], "krr": krr[:, body], "template": pred.template[:, body],
        "train_span": (float(train.t[0]), float(train.t[-1])), "test_span": (float(test.t[0]), float(test.t[-1])),
    }


def figure(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(results), 3, figsize=(15, 3.6 * len(results)),
                             gridspec_kw={"width_ratios": [1, 2, 2]})
    for row, res in zip(np.atleast_2d(axes), results):
        pts = res["pts"]
        for k in range(0, pts.shape[0], max(1, pts.shape[0] // 25)):
            row[0].plot(pts[k, :, 0], pts[k, :, 1], "-", color=plt.cm.viridis(k / pts.shape[0]), lw=1)
            row[0].plot(pts[k, 0, 0], pts[k, 0, 1], "o", color="k", ms=2)
        row[0].set_aspect("equal")
        row[0].invert_yaxis()
        unit = "px" if res["animal"].points is not None else "file units"
        row[0].set_title(f"{res['animal'].name}: midlines ({unit}, head ●)")
        for ax, ch in zip(row[1:], (0, 2)):
            t = res["t"]
            ax.plot(t, res["truth"][:, ch], color="k", lw=1, label="measured")
            ax.plot(t, res["template"][:, ch], color="0.6", lw=1, ls="--", label="phase template")
            ax.plot(t, res["krr"][:, ch], color="tab:orange", lw=1,
                    label=f"kernel ridge Γ={res['gamma_krr'][ch]:.2f}")
            ax.plot(t, res["ours"][:, ch], color="tab:blue", lw=1.2, label=f"ours Γ={res['gamma_ours'][ch]:.2f}")
            ax.set_title(f"{res['animal'].name}: {res['channels'][ch]} on held-out cycles")
            ax.set_xlabel("t (s)")
            ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(results: list[dict], sources: dict[str, Path]) -> str:
    lines = [
        "# Real animals: tracked fish and a crawling worm through `suds import` and `suds identify`",
        "",
        f"Generated by `benchmarks/organisms.py` ({stamp()}; {machine()}).  Measured numbers only.",
        "",
        "## Data",
        "",
        "Read in place from the sources below (not copied into this repository).  Every joint is taken as "
        "actuated (`suds import` default), so the identified outputs are the body velocity channels ξx, ξy, ξθ "
        "of the body link.",
        "",
    ]
    credits = {
        "fishmechr": "the R package **fishmechr** by Eric Tytell (Tufts University), example files under its "
                     "`data-raw/`",
        "movement_cloud": "OpenWorm's **movement_cloud** (the Open Worm Movement Database's web viewer), its "
                          "example file: a recording of the Schafer lab's single-worm tracker (MRC Laboratory of "
                          "Molecular Biology, Laura Grundy, 2010; method of Yemini et al. 2013, "
                          "doi:10.1038/nmeth.2560)",
    }
    for key in dict.fromkeys(res["animal"].source for res in results):
        url, _, licence = SOURCES[key]
        lines += [f"From {credits[key]}: {url}, commit `{source_commit(sources[key])}`, licence **{licence}** "
                  "(its `LICENSE.md`).", ""]
        for res in results:
            a, imp = res["animal"], res["import"]
            if a.source != key:
                continue
            fps = f"{a.fps:g} fps" if a.fps else "times from the file"
            lines.append(f"- **{a.name}** — {a.species}: `{a.file}`, {fps}, {a.note}. "
                         f"{imp['frames']} frames, {imp['kept']} kept ({imp['lost']['frames']} lost by the "
                         f"tracker, dropped), chain of {imp['links']} links, gait {imp['gait_hz']:.3g} Hz "
                         "(dominant frequency of the joint angles); head–tail swaps found by continuity: "
                         f"{imp['head_tail']['swapped']} frames, {imp['head_tail']['unlinked']} frames where the "
                         "midline read alike either way round.")
        lines.append("")
    lines += [
        f"Pixel size: not stated by the fish files; imported with a nominal {PX * 1e3:g} mm per pixel, which "
        "changes no Γ below.  The worm's file states its unit (`\"micrometers\"`, read by the WCON unit grammar).",
        "",
        "## Held-out Γ per body channel",
        "",
        "Split: the first gait cycles train (zebrafish 12, prickleback 3: its slow gait gives about 5 "
        "cycles in the whole file; worm 9 of its 18), every later cycle is held out "
        "(`suds identify --train-cycles N`).  "
        "Γ = 1 − Σ|prediction − measured| / Σ|phase-only template − measured| on "
        "the held-out intervals (0: no better than the template).  Kernel ridge: `benchmarks/peers.py` `krr` "
        "(RBF, standardised [r̄, ṙ_a, cos φ, sin φ], α and γ by blocked CV on the training cycles) on the "
        "identifier's own inputs and template; both fitted without regridding (intervals between the file's "
        "own frames).",
        "",
        "| animal | held-out cycles | channel | Γ ours | Γ kernel ridge |",
        "|---|---|---|---|---|",
    ]
    for res in results:
        cyc = res["identify"]["test_cycles"]
        for c, g, k in zip(res["channels"], res["gamma_ours"], res["gamma_krr"]):
            lines.append(f"| {res['animal'].name} | {cyc} | {c} | {g:.3f} | {k:.3f} |")
    lines += ["", "`suds identify` itself (regridded onto a uniform clock first, body scored over the pose "
              "stream's intervals; same split):", ""]
    for res in results:
        cli = res["identify"]
        lines.append(f"- {res['animal'].name}: `suds identify --train-cycles {res['animal'].train}`: "
                     f"Γ body {cli['gamma_body']:.3f}, regressor set {cli['regressors']}, "
                     f"{cli['parameters_per_output']} parameters per output, train {cli['train_cycles']} / test "
                     f"{cli['test_cycles']} cycles; kernel ridge {res['krr_params']}.")
    lines += ["", "The live estimator's algorithm (`suds identify --streaming`, the model the estimator node "
              "would publish after the training cycles; same split, scored the same way; the phase initialised "
              "on the first 5 cycles, the prickleback's 3):", ""]
    for res in results:
        live = res["streaming"]
        if "error" in live:
            lines.append(f"- {res['animal'].name}: no model: `{live['error']}` (its training cycles span less "
                         "than the phaser's first cycles at the file's gait frequency).")
            continue
        lines.append(f"- {res['animal'].name}: Γ body {live['gamma_body']:.3f}, "
                     f"{live['parameters_per_output']} parameters per output (the candidate with the lowest "
                     f"prequential loss), running Γ body {live['running_gamma']['body']:.3f}.")
    lines += ["", "## `suds diagnose` against the imported model file", "",
              "The model file `suds import` writes is a nominal guess (resistive force theory with a swimmer's "
              "c⊥/c∥ = 2, the measured link lengths, every joint driven); `suds diagnose REC --model REC.yaml` "
              "says where the animal departs from it (train on the first half of the cycles, held-out second half):",
              ""]
    for res in results:
        d = res["diagnose"]
        if not d["mismatch"]:
            found = "no significant mismatch"
        else:
            parts = []
            for e in d["effects"]:
                ps = ", ".join(parameter_text(k, v, e["stderr"][k], e["at_bound"].get(k))
                               for k, v in e["parameters"].items())
                parts.append(f"`{e['name']}`{' on ' + e['target'] if e['target'] else ''} {ps}")
            found = "; ".join(parts) or "no catalogue effect"
            if d["unexplained"]:
                found += " (unexplained mismatch remains)"
            found += f"; held-out improvement {d['fit']['improvement']:.2f}"
        located = ", ".join(loc["channel"] for loc in d["located"]) or "none"
        lines.append(f"- {res['animal'].name}: located {located}; {found}.")
    lines += ["", "Reading the figure: the prickleback's ξθ jumps from frame to frame at 60 fps, far above its "
              "0.45 Hz gait; both models follow it through the joint velocities of the same jittering keypoints, "
              "so its high Γ on ξθ reflects that kinematic coupling more than a swimming model.  The held-out "
              "sets are short (2 prickleback cycles; 13 zebrafish cycles of about 10 frames each)."]
    worm = next((res for res in results if res["animal"].name == "worm"), None)
    if worm is not None:
        g, k = dict(zip(worm["channels"], worm["gamma_ours"])), dict(zip(worm["channels"], worm["gamma_krr"]))
        lines[-1] += (f"  The crawling worm's forward and turning velocities are predicted (ξx {g['xi_x']:.2f}, ξθ "
                      f"{g['xi_theta']:.2f}; kernel ridge {k['xi_x']:.2f}, {k['xi_theta']:.2f}); its sideways "
                      f"velocity ξy is not, by either model (Γ {g['xi_y']:.2f} and {k['xi_y']:.2f}: no better than "
                      "its phase average).")
    lines += ["", "![data and held-out predictions](organisms.png)", ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for key, (url, default, _) in SOURCES.items():
        ap.add_argument(f"--{key.replace('_', '-')}", type=Path, default=default,
                        help=f"checkout or bare git mirror of {url} (default {default})")
    args = ap.parse_args()
    sources = {key: getattr(args, key) for key in SOURCES}
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    with tempfile.TemporaryDirectory() as tmp:
        results = [one(a, sources[a.source], Path(tmp)) for a in ANIMALS]
    figure(results, RESULTS / "organisms.png")
    write("organisms.md", report(results, sources))


if __name__ == "__main__":
    main()
