"""Tokens of the synthetic tables: 32 lowercase hex characters like nuScenes', never from the clock.

Vocabulary records (category, attribute, sensor, map) get tokens derived from their names, the same in every
seed, like the fixed tokens of nuScenes' global tables; everything else draws them from the seeded generator.
"""

from __future__ import annotations

import hashlib

import numpy as np


def name_token(kind: str, name: str) -> str:
    """The token of a vocabulary entry, e.g. name_token("category", "vehicle.car")."""
    return hashlib.md5(f"nuparquet.synth/{kind}/{name}".encode()).hexdigest()


def random_tokens(rng: np.random.Generator, n: int) -> list[str]:
    """n uuid4-like tokens drawn from the seeded generator."""
    raw = rng.bytes(16 * n).hex()
    return [raw[i:i + 32] for i in range(0, 32 * n, 32)]
