"""Filter machinery shared by the papers: the UKF core and the NEES null distribution."""
