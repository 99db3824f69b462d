"""From 2D landmarks to 3D joint angles: the humanoid model and its uDEAS fit (numpy and numba only)."""
