"""Test configuration: hypothesis runs derandomized (reproducible CI) and
writes no example database into the repository."""

try:
    from hypothesis import settings

    settings.register_profile("abkit", derandomize=True, database=None, deadline=None)
    settings.load_profile("abkit")
except ImportError:  # pragma: no cover - hypothesis is part of abkit[test]
    pass
