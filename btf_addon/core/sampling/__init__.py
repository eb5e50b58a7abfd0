"""Sampling: low-discrepancy sequences (``sequences.py``), the environment map's
importance sampling and virtual lights (``envmap.py``), and the importance tables of measured
BTFs (``btf_importance.py``). Imports only the modules directly under core/."""
