from coordinator.sample_size import covering_size, n_eps


def test_lemma_2_sample_sizes():
    assert n_eps(0.001, 0.01) == 4603  # the paper's figure (Lemma 2 text)
    assert n_eps(0.001, 0.1) == 2302
    assert n_eps(0.01, 0.05) == 299
    # the rule itself: (1 - eps)^N <= beta, and N - 1 does not suffice
    for eps, beta in [(0.001, 0.01), (0.05, 0.2), (0.3, 0.001)]:
        n = n_eps(eps, beta)
        assert (1 - eps) ** n <= beta < (1 - eps) ** (n - 1)


def test_lemma_1_sample_size():
    assert covering_size(20 * 20 * 70, 1.0, 3) == 3500
    assert covering_size(10.0, 0.5, 1) == 10
