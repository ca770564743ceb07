"""The body's shape: triangle meshes, the shipped Itokawa mesh, surface models and the trajectory's surface check."""
