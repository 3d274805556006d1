"""What a run measured: the summary, task timing, clearances, deadlocks, people metrics, plots and
the report."""
