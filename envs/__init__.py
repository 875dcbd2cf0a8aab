"""Gymnasium environments of hgo_mj (installed as ``hgo_mj.envs``)."""
