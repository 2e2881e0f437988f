"""Scenario schema, runner, metrics, reports and campaigns."""
