"""placement stage (see DESIGN.md)."""
