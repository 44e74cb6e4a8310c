"""evaluate stage (see DESIGN.md)."""
