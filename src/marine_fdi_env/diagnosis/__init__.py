"""The diagnosers: the thesis's distributed observer / adaptive-threshold / fault-signature scheme
(chapter 5-6; 4 monitoring agents, 19 monitoring modules, local and global decision logic) and the
``sequential`` diagnoser (CUSUM tests on the same residuals, :mod:`.sequential`)."""
