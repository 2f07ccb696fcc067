"""Pydantic request and response models (the HTTP contract, see shared API.md)."""
