"""Terms and parameters: footprints as blocks on explicit DOFs."""

import numpy as np
import pytest

from twin.fem.parameters import Parameter, Term


def test_term_checks_its_block():
    with pytest.raises(ValueError, match="2x2 block"):
        Term("K", (0, 1), np.eye(3))
    with pytest.raises(ValueError, match="matrix kind"):
        Term("X", (0,), [[1.0]])


def test_footprint_sums_overlapping_terms():
    p = Parameter(
        "p", 2.0, "N/m", (Term("K", (0, 2), np.ones((2, 2))), Term("K", (2,), [[3.0]]), Term("C", (1,), [[1.0]]))
    )
    K = p.footprint("K", 3).toarray()
    np.testing.assert_array_equal(K, [[1, 0, 1], [0, 0, 0], [1, 0, 4]])
    assert p.dofs == (0, 1, 2) and p.kinds == ("C", "K")
    assert p.footprint("M", 3).nnz == 0
