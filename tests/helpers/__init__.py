"""Shared helpers of the tests: fixed sample messages and the child process of the bus tests."""
