"""What a user reads: summary.json, certificate.json, status, progress, the HTML report, comparison with a reference, figures."""
