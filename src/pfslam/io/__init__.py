"""Readers and writers for logs, maps and trajectories."""
