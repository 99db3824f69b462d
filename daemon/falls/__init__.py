"""Fall detection over the stream of fit results, the event journal, hooks and joint-angle history."""
