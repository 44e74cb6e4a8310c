"""experiment stage (see DESIGN.md)."""
