"""Identification with torch: canonical state, regressors H, baselines, output-error training,
the auto-encoder. Never imports CasADi; exports plain numpy callables for ``analysis``."""
