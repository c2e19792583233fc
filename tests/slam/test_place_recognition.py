"""Features, the incremental bag of words and PnP verification on synthetic textured planes."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.slam.features import Features, extract
from longslam.slam.place_recognition import (SUPPORT_PIXELS, Vocabulary, depth_held_transform, refine_3d,
                                             match_descriptors, refine_3d_checked, verify)

INTR = Intrinsics.from_fov(320, 240, 90.0)  # fx = fy = 160
PLANE_Z = 2.0
MARGIN = 60  # canvas border so shifted views never run off the texture


def texture(seed: int) -> np.ndarray:
    """A canvas of random shapes and text: distinctive corners for ORB."""
    rng = np.random.default_rng(seed)
    h, w = INTR.height + 2 * MARGIN, INTR.width + 2 * MARGIN
    canvas = np.full((h, w, 3), 128, np.uint8)
    for _ in range(60):
        colour = tuple(int(c) for c in rng.integers(0, 256, 3))
        kind = rng.integers(0, 3)
        x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
        if kind == 0:
            cv2.rectangle(canvas, (x, y), (x + int(rng.integers(5, 50)), y + int(rng.integers(5, 50))), colour, -1)
        elif kind == 1:
            cv2.circle(canvas, (x, y), int(rng.integers(3, 25)), colour, -1)
        else:
            text = "".join(chr(c) for c in rng.integers(65, 91, 4))
            cv2.putText(canvas, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, float(rng.uniform(0.4, 1.2)), colour, 2)
    return canvas


def view(canvas: np.ndarray, tx: float = 0.0, ty: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Image and depth of the plane at PLANE_Z seen by a camera translated by (tx, ty) metres.

    A camera moved by t sees a fronto-parallel plane shifted by -f t / Z pixels.
    """
    du, dv = INTR.fx * tx / PLANE_Z, INTR.fy * ty / PLANE_Z
    m = np.array([[1.0, 0.0, -(MARGIN + du)], [0.0, 1.0, -(MARGIN + dv)]])
    rgb = cv2.warpAffine(canvas, m, (INTR.width, INTR.height), flags=cv2.INTER_LINEAR)
    depth = np.full((INTR.height, INTR.width), PLANE_Z, np.float32)
    return rgb, depth


@pytest.fixture(scope="module")
def scenes() -> list[np.ndarray]:
    return [texture(seed) for seed in range(12)]


def feats(canvas: np.ndarray, tx: float = 0.0, ty: float = 0.0) -> Features:
    rgb, depth = view(canvas, tx, ty)
    return extract(rgb, depth, INTR)


def test_features_have_points_on_the_plane(scenes):
    f = feats(scenes[0])
    assert len(f) > 200
    assert f.keypoints.shape == (len(f), 2) and f.keypoints.dtype == np.float32
    assert f.descriptors.shape == (len(f), 32) and f.descriptors.dtype == np.uint8
    assert f.points.shape == (len(f), 3) and f.points.dtype == np.float32
    assert f.valid.all()
    np.testing.assert_allclose(f.points[:, 2], PLANE_Z, atol=1e-6)
    # Back-projection must reproject to the keypoints.
    uv = f.points[:, :2] / f.points[:, 2:] * [INTR.fx, INTR.fy] + [INTR.cx, INTR.cy]
    np.testing.assert_allclose(uv, f.keypoints, atol=0.51)
    assert f.nbytes == f.keypoints.nbytes + f.descriptors.nbytes + f.points.nbytes


def test_missing_depth_gives_nan_points(scenes):
    rgb, depth = view(scenes[0])
    depth[:, : INTR.width // 2] = 0.0
    f = extract(rgb, depth, INTR)
    left = f.keypoints[:, 0] < INTR.width // 2 - 1
    assert left.any() and (~left).any()
    assert not f.valid[left].any()
    assert f.valid[f.keypoints[:, 0] > INTR.width // 2 + 1].all()


@pytest.mark.parametrize("tx, ty", [(0.10, 0.0), (-0.07, 0.04)])
def test_verify_recovers_translation(scenes, tx, ty):
    candidate = feats(scenes[0])
    query = feats(scenes[0], tx, ty)
    result = verify(query, candidate, INTR)
    assert result.accepted, result.reason
    assert result.inliers >= 20
    assert result.transform.shape == (4, 4)
    # Query camera pose in the candidate frame: translated by (tx, ty, 0), no rotation.
    np.testing.assert_allclose(result.transform[:3, 3], [tx, ty, 0.0], atol=0.03)
    np.testing.assert_allclose(result.transform[:3, :3], np.eye(3), atol=0.02)


def _shifted(transform: np.ndarray, dx: float) -> np.ndarray:
    out = transform.copy()
    out[0, 3] += dx
    return out


def test_depth_supports_a_true_link_and_not_one_half_a_metre_off(scenes):
    candidate, query = feats(scenes[0]), feats(scenes[0], 0.10, 0.0)
    pnp = verify(query, candidate, INTR).transform
    true = refine_3d_checked(query, candidate, pnp, INTR.fx)
    assert true.polished and true.support >= 100
    np.testing.assert_allclose(true.transform[:3, 3], [0.10, 0.0, 0.0], atol=0.01)
    np.testing.assert_array_equal(refine_3d(query, candidate, pnp), true.transform)
    # A transform 0.5 m off (a wrong loop's size) cannot be polished back, and no match supports it.
    wrong = refine_3d_checked(query, candidate, _shifted(pnp, 0.5), INTR.fx)
    assert not wrong.polished and wrong.support < 10
    np.testing.assert_array_equal(wrong.transform, _shifted(pnp, 0.5))  # PnP's, not half polished
    # The gate is the footprint of SUPPORT_PIXELS pixels at a match's distance: 3.75 cm at 2 m,
    # so 5 cm (the floor) here; 4 cm off is supported, 8 cm is not.
    assert SUPPORT_PIXELS * PLANE_Z / INTR.fx < 0.05
    near = refine_3d_checked(query, candidate, _shifted(true.transform, 0.04), INTR.fx, min_inliers=10**6)
    far = refine_3d_checked(query, candidate, _shifted(true.transform, 0.08), INTR.fx, min_inliers=10**6)
    assert not near.polished and near.support >= 100 and far.support < 10  # measured unpolished
    assert refine_3d_checked(query, candidate, pnp, None).support == 0  # no focal length: nothing measured


def test_a_loop_keeps_the_transform_its_depth_holds(scenes):
    candidate, query = feats(scenes[0]), feats(scenes[0], 0.10, 0.0)
    pnp = verify(query, candidate, INTR).transform
    polished = refine_3d(query, candidate, pnp)
    assert depth_held_transform(query, candidate, pnp, INTR.fx, polish=False, min_support=0) is pnp
    np.testing.assert_array_equal(depth_held_transform(query, candidate, pnp, INTR.fx, True, 10), polished)
    np.testing.assert_array_equal(depth_held_transform(query, candidate, pnp, INTR.fx, False, 10), pnp)
    assert depth_held_transform(query, candidate, pnp, INTR.fx, True, 100_000) is None
    assert depth_held_transform(query, candidate, _shifted(pnp, 0.5), INTR.fx, True, 10) is None


def test_verify_rejects_unrelated_places(scenes):
    for other in range(1, 6):
        result = verify(feats(scenes[other]), feats(scenes[0]), INTR)
        assert not result.accepted
        assert result.transform is None
        assert result.reason


def test_blank_image_gives_no_features_and_is_rejected(scenes):
    blank = np.full((INTR.height, INTR.width, 3), 200, np.uint8)
    depth = np.full((INTR.height, INTR.width), PLANE_Z, np.float32)
    empty = extract(blank, depth, INTR)
    assert len(empty) == 0 and empty.descriptors.shape == (0, 32)
    result = verify(empty, feats(scenes[0]), INTR)
    assert not result.accepted and result.transform is None and "no features" in result.reason
    result = verify(feats(scenes[0]), empty, INTR)
    assert not result.accepted and "no features" in result.reason
    # No valid depth anywhere: also empty, without error.
    rgb, _ = view(scenes[0])
    assert len(extract(rgb, np.zeros_like(depth), INTR)) == 0


@pytest.mark.parametrize("index", ["bruteforce", "flat", "hnsw"])
def test_vocabulary_ranks_revisit_first(scenes, index):
    vocab = Vocabulary(index=index)
    for node, canvas in enumerate(scenes[:11]):
        words = vocab.add(node, feats(canvas).descriptors)
        assert len(words) <= vocab.max_words_per_image
    assert len(vocab) == 11 and vocab.n_words > 0
    revisit = feats(scenes[3], 0.08, -0.03).descriptors
    ranked = vocab.query(revisit, top_k=5)
    assert ranked[0][0] == 3
    assert ranked[0][1] > 2.0 * ranked[1][1]
    assert all(0.0 <= s <= 1.0 + 1e-9 for _, s in ranked)
    # A place never seen scores low everywhere.
    unseen = vocab.query(feats(scenes[11]).descriptors, top_k=1)
    assert not unseen or unseen[0][1] < 0.5 * ranked[0][1]
    # Candidate filter.
    assert [n for n, _ in vocab.query(revisit, candidates=[1, 2, 4])] and all(
        n in (1, 2, 4) for n, _ in vocab.query(revisit, candidates=[1, 2, 4])
    )


def test_vocabulary_remove_and_re_add(scenes):
    vocab = Vocabulary()
    for node, canvas in enumerate(scenes[:6]):
        vocab.add(node, feats(canvas).descriptors)
    revisit = feats(scenes[2], 0.05, 0.0).descriptors
    assert vocab.query(revisit)[0][0] == 2
    n_words = vocab.n_words
    vocab.remove(2)
    assert 2 not in vocab
    assert all(n != 2 for n, _ in vocab.query(revisit, top_k=10))
    assert vocab.n_words == n_words  # words stay for nodes that come back from long-term memory
    vocab.remove(2)  # removing twice is harmless
    vocab.add(2, feats(scenes[2]).descriptors)
    assert vocab.n_words == n_words  # the same image quantises to the words it had
    assert vocab.query(revisit)[0][0] == 2


def test_vocabulary_caps_words_per_image(scenes):
    vocab = Vocabulary(max_words_per_image=50)
    f = feats(scenes[0])
    assert len(f) > 50
    words = vocab.add(0, f.descriptors)
    assert len(words) == 50 and vocab.n_words <= 50
    assert vocab.query(np.zeros((0, 32), np.uint8)) == []
    assert Vocabulary().query(f.descriptors) == []


def test_the_faiss_indexes_find_the_words_brute_force_finds(scenes):
    descriptors = [feats(canvas).descriptors for canvas in scenes]
    vocabularies = {index: Vocabulary(index=index) for index in ("bruteforce", "flat", "hnsw")}
    words = {index: [v.add(node, d) for node, d in enumerate(descriptors)] for index, v in vocabularies.items()}
    # The exact index gives the same words (ties between equally near words aside: none here).
    assert all(np.array_equal(a, b) for a, b in zip(words["bruteforce"], words["flat"]))
    # The approximate one gives almost all of them; a miss founds a new word.
    same = np.mean(np.concatenate([a == b for a, b in zip(words["bruteforce"], words["hnsw"])]))
    assert same > 0.95, same
    assert vocabularies["hnsw"].n_words >= vocabularies["bruteforce"].n_words
    with pytest.raises(InputError, match="vocabulary index"):
        Vocabulary(index="lsh")


@pytest.mark.parametrize("index", ["flat", "hnsw"])
def test_unused_words_leave_the_index_and_held_ones_keep_their_ids(index):
    rng = np.random.default_rng(3)
    vocab = Vocabulary(max_distance=20, index=index)
    images = [rng.integers(0, 256, (100, 32), dtype=np.uint8) for _ in range(6)]
    words = [vocab.add(node, d) for node, d in enumerate(images)]
    assert vocab.n_words == 600  # random descriptors: every one founds a word
    assert not vocab.forget_unused(least=0)  # every word is held
    for node in range(4):
        vocab.remove(node)
    # 400 unused against 200 held: rebuilt over the held ones only.
    assert not vocab.forget_unused(least=400) and vocab.forget_unused(least=0)
    assert vocab.index_rebuilds == 1 and len(vocab._index_words) == 200
    # A held word is found under its old id; an unused one is no longer found, so its
    # descriptor founds a new word.
    assert np.array_equal(vocab.quantise(images[5]), words[5])
    assert np.all(vocab.quantise(images[0]) == -1)
    again = vocab.add(9, images[0])
    assert again.min() >= 600 and vocab.n_words == 700
    assert vocab.query(images[5], top_k=1)[0][0] == 5


def test_vocabulary_scores_follow_the_nodes_indexed(scenes):
    """A query keeps the idf and the nodes' norms from the last one (they change only
    with the nodes indexed). After nodes come and go, its scores must be those of scoring afresh."""
    vocab = Vocabulary(index="bruteforce")
    for node, canvas in enumerate(scenes[:6]):
        vocab.add(node, feats(canvas).descriptors)
    revisit = feats(scenes[2], 0.05, 0.0).descriptors
    before = vocab.query(revisit, top_k=6)
    assert vocab.query(revisit, top_k=6) == before  # the second query, from what the first kept
    vocab.remove(2)
    vocab.add(7, feats(scenes[7]).descriptors)
    after = vocab.query(revisit, top_k=6)
    vocab.add_words(99, np.zeros(0, np.int64))  # a node in and out: the same nodes, scored afresh
    vocab.remove(99)
    assert vocab.query(revisit, top_k=6) == after
    assert before[0][0] == 2 and all(node != 2 for node, _ in after)
    assert dict(before)[0] != dict(after)[0]  # one node fewer and one more: the idf moved


def test_a_repeated_search_is_answered_again_only_until_the_dictionary_changes():
    rng = np.random.default_rng(5)
    vocab = Vocabulary(max_distance=20, index="bruteforce")
    image = rng.integers(0, 256, (50, 32), dtype=np.uint8)
    assert np.all(vocab.quantise(image) == -1)  # an empty dictionary
    assert np.all(vocab.quantise(image) == -1)  # the same search, the same answer
    words = vocab.add(0, image)  # grows the dictionary by this image's words
    assert np.all(words >= 0)
    # A search made before the words existed must not answer now.
    assert np.array_equal(vocab.quantise(image), words)
    # Query then add (the submap method's order) gives the words a plain add gives.
    other = rng.integers(0, 256, (50, 32), dtype=np.uint8)
    fresh = Vocabulary(max_distance=20, index="bruteforce")
    fresh.add(0, image)
    vocab.query(other)
    assert np.array_equal(vocab.add(1, other), fresh.add(1, other))


def test_descriptor_matching_gives_opencv_brute_force_pairs_under_the_ratio_test():
    rng = np.random.default_rng(7)
    train = rng.integers(0, 256, (300, 32), dtype=np.uint8)
    # Queries near a train descriptor (a few bits flipped), some of them near two (a tie or an
    # ambiguous pair the ratio test refuses), and some unrelated.
    near = train[rng.integers(0, 300, 150)].copy()
    flips = rng.integers(0, 32, (150, 3))
    near[np.arange(150)[:, None], flips] ^= np.uint8(1)
    twins = np.vstack([train[:20], train[:20]])  # every query of these has two equally near
    query = np.vstack([near, rng.integers(0, 256, (100, 32), dtype=np.uint8), train[:20]])
    for a, b in ((query, train), (query, twins), (train[:1], train[:2])):
        knn = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(a, b, k=2)
        expected = np.array(
            [(m[0].queryIdx, m[0].trainIdx) for m in knn if len(m) == 2 and m[0].distance < 0.8 * m[1].distance],
            np.int64,
        ).reshape(-1, 2)
        _, first = np.unique(expected[:, 1], return_index=True)
        assert np.array_equal(match_descriptors(a, b, 0.8), expected[np.sort(first)])
    assert match_descriptors(query, twins).shape == (0, 2)  # ties refused
    assert len(match_descriptors(near, train)) > 100


def test_descriptor_matching_refuses_descriptors_that_are_not_orb_bytes():
    good = np.zeros((5, 32), np.uint8)
    with pytest.raises(InputError, match=r"descriptors must be \(N, 32\) uint8"):
        match_descriptors(good.astype(np.float32), good)
    with pytest.raises(InputError, match=r"descriptors must be \(N, 32\) uint8"):
        match_descriptors(good, np.zeros((5, 16), np.uint8))
