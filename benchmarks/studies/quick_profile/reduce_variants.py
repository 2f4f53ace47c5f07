"""How the ``quick`` ``reduce`` profile was chosen: reduce one trained run with variants of it.

    python benchmarks/studies/quick_profile/reduce_variants.py runs/tank-mlp-l10 [--rate 0.6] \
        [--only KEY ...]

Each variant is the ``quick`` ``reduce`` stage with a few options changed (``VARIANTS``); the
script trains the reduced model on the run's training data (seed 0, one torch thread) and prints
one Markdown row per variant: 100-step rollout MSE on the test split (physical units), its
ratio to the full model's, the auto-encoder's reconstruction MSE (normalised) and the time. The
first row is not trained: the linear PCA reduction of the training windows (``E``, ``D`` affine,
from :func:`canonid.learning.reduction.principal_directions`) around the full model's ``Ĥ``.
Not a speed benchmark (``run_all.py`` skips it): each variant is a few CPU minutes.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))

PLAIN = {"linear_skip": False, "lr": 1e-3}
W256 = {"encoder_hidden": [256, 256], "decoder_hidden": [256, 256]}

#: key → (description, overrides of the quick ``reduce`` stage)
VARIANTS: dict[str, tuple[str, dict[str, object]]] = {
    "quick": ("quick profile: 2 × 128 + PCA-started affine path, lr 3e-4", {}),
    "quick-lr1e-3": ("2 × 128 + PCA-started affine path, lr 1e-3", {"lr": 1e-3}),
    "plain-128": ("plain MLPs 2 × 128", PLAIN),
    "plain-256": ("plain MLPs 2 × 256", {**PLAIN, **W256}),
    "plain-512": (
        "plain MLPs 2 × 512 (paper size)",
        {**PLAIN, "encoder_hidden": [512, 512], "decoder_hidden": [512, 512]},
    ),
    "plain-128-300": (
        "plain 2 × 128, 300 epochs, curriculum 100",
        {**PLAIN, "epochs": 300, "curriculum_epochs": 100},
    ),
    "plain-128-out10": ("plain 2 × 128, output weight 10", {**PLAIN, "output_weight": 10.0}),
    "plain-256-rec10": (
        "plain 2 × 256, reconstruction weight 10",
        {**PLAIN, **W256, "reconstruction_weight": 10.0},
    ),
    "plain-256-clip": (
        "plain 2 × 256, curriculum 112, grad clip 1",
        {**PLAIN, **W256, "curriculum_epochs": 112, "grad_clip": 1.0},
    ),
    "plain-256-freeze25": (
        "plain 2 × 256, Ĥ frozen 25 %",
        {**PLAIN, **W256, "freeze_fraction": 0.25},
    ),
    "plain-256-lr3e-4": ("plain 2 × 256, lr 3e-4", {**PLAIN, **W256, "lr": 3e-4}),
    "plain-128-lr3e-3": ("plain 2 × 128, lr 3e-3", {**PLAIN, "lr": 3e-3}),
}


def main() -> int:
    import torch

    from canonid.kernel.io import read_json
    from canonid.learning import Model, evaluate
    from canonid.learning.nets import ReducedNet
    from canonid.learning.reduction import (
        latent_size,
        principal_directions,
        reconstruction_mse,
        reduce_model,
    )
    from canonid.profiles import reduce_options
    from canonid.runfolder import load_splits

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="run folder of a trained Ours (MLP/GRU) model")
    parser.add_argument("--rate", type=float, default=0.6, help="compression rate (default 0.6)")
    parser.add_argument(
        "--only",
        nargs="*",
        metavar="KEY",
        help=f"variants to train (default all): {list(VARIANTS)}",
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    unknown = sorted(set(args.only or ()) - set(VARIANTS))
    if unknown:
        parser.error(f"unknown variant(s) {unknown}; known: {sorted(VARIANTS)}")

    model = Model.load(args.run)
    dataset, train, val, test_name, _ = load_splits(read_json(args.run / "run.json", what="recipe"))
    test = list(dataset.split(test_name))
    full = evaluate(model, test, horizon=100).measured.rollout_mse
    latent = latent_size(model.net.state_dim, args.rate)
    print(
        f"{args.run}: {model.name}, ℓ = {model.window}, r = {args.rate} (n̄ = {latent} of "
        f"{model.net.state_dim}); full model's 100-step test MSE {full:.4g}\n"
    )
    print("| variant | reduced MSE | ratio | reconstruction MSE | best epoch | wall s |")
    print("|---|---|---|---|---|---|")

    def row(name: str, reduced: Model, best_epoch: object, seconds: float) -> None:
        mse = evaluate(reduced, test, horizon=100).measured.rollout_mse
        recon = reconstruction_mse(reduced, test)
        print(
            f"| {name} | {mse:.4g} | {mse / full:.3g} | {recon:.3g} | {best_epoch} | "
            f"{seconds:.0f} |",
            flush=True,
        )

    t0 = time.perf_counter()
    pca = ReducedNet.around(model.net, latent_dim=latent, encoder_hidden=(), decoder_hidden=())
    mean, comps = principal_directions(model, train, latent)
    with torch.no_grad():
        pca.encoder[0].weight.copy_(torch.as_tensor(comps))
        pca.encoder[0].bias.copy_(torch.as_tensor(-comps @ mean))
        pca.decoder[0].weight.copy_(torch.as_tensor(comps.T))
        pca.decoder[0].bias.copy_(torch.as_tensor(mean))
    row("linear PCA reduction, untrained", Model(pca, model.norm), "-", time.perf_counter() - t0)
    for key in VARIANTS if args.only is None else args.only:
        name, overrides = VARIANTS[key]
        train_opts, red_opts = reduce_options("quick", seed=0, device="cpu", **overrides)
        t0 = time.perf_counter()
        res = reduce_model(
            model, train, val, compression=args.rate, options=train_opts, reduction=red_opts
        )
        row(name, res.model, res.best_epoch, time.perf_counter() - t0)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
