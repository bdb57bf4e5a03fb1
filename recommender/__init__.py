"""Wrap-format search, policies, reports and the `wrapbench` command line."""
