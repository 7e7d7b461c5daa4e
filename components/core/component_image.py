"""What every component image promises the operator, which builds pods for images it never sees."""

COMPONENT_UID = 10001
"""The user Coral's component images run as (`coral`, USER 10001:10001 in components/Dockerfile);
the operator hands the robot folders a component writes to this user."""
