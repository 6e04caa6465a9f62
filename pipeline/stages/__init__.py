"""The Hydra entry points, one per stage (``python -m pipeline <stage>``), and what they share."""
