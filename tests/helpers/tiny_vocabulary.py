"""The smallest sound ORB vocabulary file, for tests that need one without building it."""

TINY_VOCABULARY = "2 1 0 0\n" + ("0 1 " + " ".join(["7"] * 32) + " 1.0\n") * 2  # k 2, L 1: a root and 2 words
