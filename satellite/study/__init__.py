"""The paired study over seeds (``isf-satellite study``) and its statistics."""
