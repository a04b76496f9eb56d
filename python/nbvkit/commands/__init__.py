"""Subcommands of the nbvkit command line (see nbvkit.cli)."""
