"""Identification with torch: canonical state, the four models, output-error training,
evaluation and the numpy export. Never imports CasADi or datagen.

Typical use (``train``, ``val``, ``test``: sequences of objects with ``.u``, ``.y``)::

    from canonid.learning import TrainOptions, evaluate, fit

    result = fit(train, val, model="mlp", window=10, options=TrainOptions(epochs=200))
    scores = evaluate(result.model, test, horizon=100)
    H = result.model.export()          # numpy: H.H(z, u), H.simulate(u, y_burn_in)
    reduced = reduce_model(result.model, train, val, compression=0.6).model   # n̄ states
"""

from canonid.learning.data import Normalisation, Series, as_series
from canonid.learning.evaluate import Evaluation, Scores, evaluate
from canonid.learning.export import NumpyModel
from canonid.learning.model import Model
from canonid.learning.nets import NETS, SequenceModel, UnknownModelError, build_net, model_names
from canonid.learning.reduction import ReductionOptions, latent_size, reduce_model
from canonid.learning.training import EpochReport, FitResult, OptionError, TrainOptions, fit

__all__ = [
    "NETS",
    "EpochReport",
    "Evaluation",
    "FitResult",
    "Model",
    "Normalisation",
    "NumpyModel",
    "OptionError",
    "ReductionOptions",
    "Scores",
    "SequenceModel",
    "Series",
    "TrainOptions",
    "UnknownModelError",
    "as_series",
    "build_net",
    "evaluate",
    "fit",
    "latent_size",
    "model_names",
    "reduce_model",
]
