"""The theory, numerically: γ_f, α_ℓ, the Proposition 2 bound and checks of learned models.

Never imports torch: learned models arrive as plain numpy callables exported by ``learning``.
Every estimate says whether it is a lower bound, an upper bound or an estimate.
"""
