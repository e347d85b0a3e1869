"""Crossing methods: the protocol (base), the methods, and the registry of names users can extend."""
