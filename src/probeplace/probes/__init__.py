"""probes stage (see DESIGN.md)."""
