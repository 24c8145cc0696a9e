"""pdem benchmarks (``make bench``): throughput of a dense settled bed; see __main__.py."""
