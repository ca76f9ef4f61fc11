"""KUKA's connector (KUKAVARPROXY) against the KRC simulator."""
