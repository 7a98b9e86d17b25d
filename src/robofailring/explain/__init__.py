"""Explaining an alarm: the failure report (eq. 8), Appendix B's prompt and the VLM client."""
