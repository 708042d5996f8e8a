"""Side-by-side benchmarks against peers (see docs/architecture.md, "Standards")."""
