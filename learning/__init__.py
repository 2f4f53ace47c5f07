"""Identification with torch: canonical state, the four models, output-error training,
evaluation and the numpy export. Never imports CasADi or datagen.

Typical use (``train``, ``val``, ``test``: sequences of :class:`canonid.kernel.dataset.Trajectory`,
or of any objects with ``.u``, ``.y``)::

    from canonid.learning import TrainOptions, evaluate, fit

    result = fit(train, val, model="mlp", window=10, options=TrainOptions(epochs=200))
    scores = evaluate(result.model, test, horizon=100)
    H = result.model.export()          # numpy: H.H(z, u), H.simulate(u, y_burn_in)
    reduced = reduce_model(result.model, train, val, compression=0.6).model   # n̄ states

The names below are imported lazily (PEP 562): importing the package does not load torch.
"""

from __future__ import annotations

from canonid.kernel.lazy import lazy_exports

_EXPORTS = {
    "Candidate": "canonid.learning.search",
    "Normalisation": "canonid.learning.data",
    "Evaluation": "canonid.learning.evaluate",
    "Scores": "canonid.learning.evaluate",
    "evaluate": "canonid.learning.evaluate",
    "NumpyModel": "canonid.learning.export",
    "Model": "canonid.learning.model",
    "NETS": "canonid.learning.nets",
    "SequenceModel": "canonid.learning.nets",
    "UnknownModelError": "canonid.learning.nets",
    "build_net": "canonid.learning.nets",
    "model_names": "canonid.learning.nets",
    "ReductionOptions": "canonid.learning.reduction",
    "Search": "canonid.learning.search",
    "candidate_table": "canonid.learning.search",
    "search": "canonid.learning.search",
    "latent_size": "canonid.learning.reduction",
    "reduce_model": "canonid.learning.reduction",
    "average_members": "canonid.learning.members",
    "EpochReport": "canonid.learning.training",
    "FitResult": "canonid.learning.training",
    "OptionError": "canonid.learning.training",
    "TrainOptions": "canonid.learning.training",
    "fit": "canonid.learning.training",
}

__all__ = sorted(_EXPORTS)

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
