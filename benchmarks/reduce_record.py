"""The tank's reductions the Reduction page quotes: one reduction and a sweep, from their files.

``canonid reduce RUN --compression R`` writes ``reduction.json`` and ``metrics.json`` into its run
folder; ``canonid reduce RUN RUN … --sweep`` writes ``sweep.json``. This script reads one of each
and writes the section "Reduction: tank" of the records, so that the page quotes a measurement:

    python reduce_record.py --single runs/tank-mlp-l10-r60 --sweep runs/sweep-main/sweep.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from _results import record

SECTION = "Reduction: tank"


def _read(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def single_lines(folder: Path) -> list[str]:
    """The full model and its reduction on the test split: rollout MSE against y and y_clean as
    the reduction scored both (``reduction.json``), and the noise-free fit of each simulation
    (``metrics.json`` of each run folder; the full model's folder from ``run.json``)."""
    found = _read(folder / "reduction.json")
    reduced = _read(folder / "metrics.json")
    source = Path(_read(folder / "run.json")["source_run"])  # its absolute path
    fit = {
        "full": _read(source / "metrics.json")["clean"]["fit_percent"],
        "reduced": reduced["clean"]["fit_percent"],
    }
    rows = [
        (f"full Ours (MLP), ℓ = {found['window']}", found["state_dim"], "full_", fit["full"]),
        (
            f"reduced, r = {100 * found['compression']:.0f} %",
            found["latent_dim"],
            "",
            fit["reduced"],
        ),
    ]
    lines = [
        f"Test split, {reduced['n_rollouts']} rollouts of {reduced['rollout_horizon']} steps:",
        "",
        "| model | states | vs measured y | vs y_clean | fit % (y_clean, after n_init = "
        f"{reduced['n_init']}) |",
        "|---|---:|---:|---:|---:|",
    ]
    for label, states, prefix, fit_percent in rows:
        lines.append(
            f"| {label} | {states} | {found[prefix + 'rollout_mse']:.3e} | "
            f"{found[prefix + 'rollout_mse_clean']:.3e} | {fit_percent:.2f} |"
        )
    ratio = found["rollout_mse"] / found["full_rollout_mse"]
    clean = found["rollout_mse_clean"] / found["full_rollout_mse_clean"]
    lines += [
        "",
        f"Reduced over full: {ratio:.3g}× (measured), {clean:.3g}× (noise-free); the reduction "
        f"trained {found['epochs_run']} epochs (best {found['best_epoch']}) in "
        f"{found['seconds']:.0f} s of wall time.",
    ]
    return lines


def sweep_lines(path: Path) -> list[str]:
    """Every (ℓ, r) of a sweep: reconstruction MSE, the reduced model's rollout MSE (mean ± std
    over its seeds) and the full model's."""
    body = _read(path)
    lines = [
        "| ℓ | r | n̄ / dim z | reconstruction MSE (normalised) | reduced | reduced, std | full "
        "| reduced / full |",
        "|---:|---:|---|---:|---:|---:|---:|---:|",
    ]
    for row in sorted(body["summary"], key=lambda r: (r["window"], r["compression"])):
        lines.append(
            f"| {row['window']} | {100 * row['compression']:.0f} % | {row['latent_dim']} / "
            f"{row['state_dim']} | {row['reconstruction_mse_mean']:.3g} | "
            f"{row['rollout_mse_mean']:.3e} | {row['rollout_mse_std']:.2e} | "
            f"{row['full_rollout_mse']:.3e} | "
            f"{row['rollout_mse_mean'] / row['full_rollout_mse']:.3g} |"
        )
    seeds = sorted({row["seeds"] for row in body["summary"]})
    return [
        f"Sweep (`{path.name}`), 100-step MSE against the measured y on the test split, mean and "
        f"std over {', '.join(map(str, seeds))} seed(s):",
        "",
        *lines,
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--single", type=Path, required=True, help="a reduction's run folder")
    parser.add_argument("--sweep", type=Path, help="a sweep's sweep.json")
    args = parser.parse_args(argv)
    lines = single_lines(args.single)
    if args.sweep is not None:
        lines += ["", *sweep_lines(args.sweep)]
    return record(SECTION, "\n".join(lines))


if __name__ == "__main__":
    raise SystemExit(main())
