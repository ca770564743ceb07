"""Satellite orbit safety around asteroid Itokawa on the isf_robot core."""

__all__: list[str] = []
