"""Subcommands of the ``recon`` CLI, one module each (see ``recon.cli``)."""
