"""Robustness: injected sensor faults and the stress suite of the filters."""
