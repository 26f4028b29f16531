"""Model fitting for the manipulation chain (Section III of Dang & Allen): still, line, circle, BIC selection."""
