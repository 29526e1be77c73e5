"""``python -m stepnc_graph.cli``: the same as the ``stepnc-graph`` command."""

from stepnc_graph.cli import main

main()
