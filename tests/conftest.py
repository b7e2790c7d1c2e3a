from hypothesis import settings

settings.register_profile("ci", derandomize=True, deadline=None, max_examples=100)
settings.load_profile("ci")


def pytest_collection_finish(session) -> None:
    """Start test_warm's fresh-cache compile at once, beside the rest of the session."""
    import test_warm

    if any(test_warm._WARM_TEST in item.nodeid for item in session.items):
        from fuzzypos._kernels import compiled

        if compiled():
            test_warm.start_in_background(session.config)


def pytest_sessionfinish(session) -> None:
    import test_warm

    test_warm.stop_in_background(session.config)
