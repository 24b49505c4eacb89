"""The references' FFT correlation (cvkit._fft): NumPy's FFT, the same bits as SciPy's."""
import numpy as np
import pytest
import scipy.fft

from cvkit._fft import correlate_valid, fast_length


def test_fast_length_is_scipys_next_fast_len_for_real_transforms():
    assert [fast_length(n) for n in range(1, 5001)] == [scipy.fft.next_fast_len(n, real=True) for n in range(1, 5001)]


@pytest.mark.parametrize("n", [0, -3])
def test_fast_length_refuses_a_length_below_one(n):
    with pytest.raises(ValueError, match="n must be a positive length"):
        fast_length(n)


def _with_scipy(image, kernel):
    """The correlation as cvkit computed it with scipy.fft before."""
    kh, kw = kernel.shape
    shape = tuple(scipy.fft.next_fast_len(int(n), real=True) for n in image.shape[:2])
    spectrum = scipy.fft.rfft2(image, shape, axes=(0, 1))
    kernel_spectrum = scipy.fft.rfft2(kernel[::-1, ::-1], shape)
    if image.ndim == 3:
        kernel_spectrum = kernel_spectrum[:, :, None]
    spectrum *= kernel_spectrum
    full = scipy.fft.irfft2(spectrum, shape, axes=(0, 1))
    return full[kh - 1 : image.shape[0], kw - 1 : image.shape[1]]


def test_the_same_bits_as_scipy_fft_on_random_sizes():
    rng = np.random.default_rng(7)
    for _ in range(120):
        h, w = rng.integers(1, 160, 2)
        shape = (h, w, 3) if rng.random() < 0.3 else (h, w)
        image = rng.normal(size=shape) * rng.uniform(0.01, 300)
        kernel = rng.normal(size=(rng.integers(1, min(h, 20) + 1), rng.integers(1, min(w, 20) + 1)))
        ours = correlate_valid(image, kernel)
        assert ours.flags.c_contiguous
        np.testing.assert_array_equal(ours, _with_scipy(image, kernel), err_msg=f"image {shape}, kernel {kernel.shape}")


def test_equals_direct_summation_and_leaves_its_inputs_alone():
    rng = np.random.default_rng(3)
    image, kernel = rng.normal(size=(31, 40, 2)), rng.normal(size=(6, 9))
    before = image.copy(), kernel.copy()
    direct = np.stack([sum(kernel[m, n] * image[m : m + 26, n : n + 32, c] for m in range(6) for n in range(9))
                       for c in range(2)], axis=-1)
    np.testing.assert_allclose(correlate_valid(image, kernel), direct, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(image, before[0])
    np.testing.assert_array_equal(kernel, before[1])


def test_the_references_import_no_scipy():
    import subprocess
    import sys

    code = ("import sys, numpy as np, cvkit.filters as f, cvkit.detection as d\n"
            "import cvkit.filters._linear as lin, cvkit.detection._template as tem\n"
            "calls = []\n"
            "def counted(fft):\n"
            "    return lambda *a: calls.append(1) or fft(*a)\n"
            "lin.correlate_valid_fft = counted(lin.correlate_valid_fft)\n"
            "tem.correlate_valid_fft = counted(tem.correlate_valid_fft)\n"
            "img = np.random.default_rng(0).normal(size=(60, 70))\n"
            "f.correlate(img, np.ones((9, 9)))\n"
            "d.match_template(img, img[10:30, 10:35], 'ncc')\n"
            "print(len(calls), sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "2 []", out  # both took the FFT route, and no SciPy was loaded
