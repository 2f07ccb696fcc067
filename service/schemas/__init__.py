"""Pydantic request and response models (the HTTP contract, see docs/API.md)."""
