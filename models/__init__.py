"""MJCF models of the hgo_mj plants (installed as ``hgo_mj.models``; data files only)."""
