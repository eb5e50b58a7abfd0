"""Command-line tools: ``python -m btf_addon <command>`` (see ``--help``)."""
