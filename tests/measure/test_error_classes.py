"""Which exit code an unexpected exception gets (:func:`study.errors.user_error`): the machine's problems — a name
that is not UTF-8, a missing package, a full disk reported by a C++ writer, dying Dask workers — are exit 3, not
"internal error" (4); anything else unexpected stays 4. One line each."""

import errno

import pytest

from study.errors import ENVIRONMENT, INTERNAL, user_error


def killed_worker():
    cls = type("KilledWorker", (Exception,), {})
    return cls("case 3 killed 3 times")


@pytest.mark.parametrize(
    "err, words",
    [
        (UnicodeEncodeError("utf-8", "\udcff/out", 0, 1, "surrogates not allowed"), "not valid UTF-8"),
        (UnicodeDecodeError("utf-8", b"\xff", 0, 1, "invalid start byte"), "not valid UTF-8"),
        (
            ModuleNotFoundError("No module named 'charset_normalizer'", name="charset_normalizer"),
            "charset_normalizer",
        ),
        (RuntimeError("Bitmap::write(): No space left on device"), "No space left"),
        (OSError(errno.ENOSPC, "No space left on device"), "No space left"),
        (killed_worker(), "Dask worker died"),
    ],
)
def test_machine_problems_are_exit_3(err, words):
    out = user_error(err)
    assert out.code == ENVIRONMENT and words in str(out) and "\n" not in str(out), str(out)


def test_a_bug_stays_internal():
    out = user_error(ZeroDivisionError("division by zero"))
    assert out.code == INTERNAL and "ZeroDivisionError" in str(out)
    assert user_error(RuntimeError("index out of range")).code == INTERNAL
