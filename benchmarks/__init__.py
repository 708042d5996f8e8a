"""Side-by-side benchmarks against peers (see DESIGN.md, "Standards")."""
