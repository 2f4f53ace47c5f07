"""Named network options: what a new run gets by default, and the paper's configuration.

Plain data kept in :mod:`canonid.kernel.catalog` (so that the command line shows them without
importing torch); see it for how each was chosen.
"""

from canonid.kernel.catalog import DEFAULT_NET_OPTIONS, PAPER_NET_OPTIONS, net_options

__all__ = ["DEFAULT_NET_OPTIONS", "PAPER_NET_OPTIONS", "net_options"]
