"""Knot identity: writhe, knot type (topoly, in an isolated worker process), chirality."""
