"""Problem families (they know nothing about strategies)."""
