import os
from pathlib import Path

import numpy as np
import pytest

from handflow.plugins.segmenter import LetterGenerator, candidate_set, train_class_models

SHARED = Path(os.environ.get("HANDFLOW_SHARED_DATA", "/work/shared/data"))  # real datasets; tests skip without them


@pytest.fixture(scope="session")
def synthetic():
    """Four synthetic letter classes, 3 train / 2 validation / 2 test samples each."""
    return LetterGenerator(n_classes=4, random_state=1, noise=0.01).dataset((3, 2, 2))


@pytest.fixture(scope="session")
def ukr_models(synthetic):
    """Real structured UKR manifolds, one per synthetic class."""
    return train_class_models(synthetic, n_steps=100, random_state=0)


@pytest.fixture(scope="session")
def candidates(ukr_models):
    return candidate_set(ukr_models)


@pytest.fixture(scope="session")
def two_letters(synthetic):
    """Test sample of class A followed by one of class B, with the true class indices."""
    a = next(t.data for t in synthetic.test if t.label == "A")
    b = next(t.data for t in synthetic.test if t.label == "B")
    return np.vstack([a, b]), np.r_[np.zeros(len(a), int), np.ones(len(b), int)]
