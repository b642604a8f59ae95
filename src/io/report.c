/* Named numbers of a run, for HDF5 attributes and one JSON line (report.h). */
#include <report.h>
#include <sys/resource.h>

typedef struct {
  char         *name;
  PetscDataType type;
  PetscReal     r;
  PetscInt      i;
  char         *s;
} ReportEntry;

struct _p_Report {
  MPI_Comm     comm;
  PetscInt     n, nalloc;
  ReportEntry *e;
};

PetscErrorCode ReportCreate(MPI_Comm comm, Report *report)
{
  PetscFunctionBeginUser;
  PetscCall(PetscNew(report));
  (*report)->comm = comm;
  PetscFunctionReturn(0);
}

PetscErrorCode ReportDestroy(Report *report)
{
  Report r = *report;

  PetscFunctionBeginUser;
  if (!r) PetscFunctionReturn(0);
  for (PetscInt k = 0; k < r->n; k++) {
    PetscCall(PetscFree(r->e[k].name));
    PetscCall(PetscFree(r->e[k].s));
  }
  PetscCall(PetscFree(r->e));
  PetscCall(PetscFree(*report));
  PetscFunctionReturn(0);
}

/* The entry called `name`, appended if new. */
static PetscErrorCode ReportEntryGet(Report r, const char name[], PetscDataType type, ReportEntry **entry)
{
  PetscFunctionBeginUser;
  for (const char *c = name; *c; c++) PetscCheck((*c >= 'a' && *c <= 'z') || (*c >= '0' && *c <= '9') || *c == '_', PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "Report entry name \"%s\" is not made of [a-z0-9_]", name);
  for (PetscInt k = 0; k < r->n; k++) {
    PetscBool same;
    PetscCall(PetscStrcmp(r->e[k].name, name, &same));
    if (same) {
      *entry = &r->e[k];
      PetscCall(PetscFree((*entry)->s));
      (*entry)->type = type;
      PetscFunctionReturn(0);
    }
  }
  if (r->n == r->nalloc) {
    ReportEntry *e;
    r->nalloc = PetscMax(32, 2 * r->nalloc);
    PetscCall(PetscCalloc1(r->nalloc, &e));
    if (r->n) PetscCall(PetscArraycpy(e, r->e, r->n));
    PetscCall(PetscFree(r->e));
    r->e = e;
  }
  *entry = &r->e[r->n++];
  PetscCall(PetscMemzero(*entry, sizeof(**entry)));
  PetscCall(PetscStrallocpy(name, &(*entry)->name));
  (*entry)->type = type;
  PetscFunctionReturn(0);
}

PetscErrorCode ReportSetReal(Report r, const char name[], PetscReal value)
{
  ReportEntry *e;

  PetscFunctionBeginUser;
  PetscCall(ReportEntryGet(r, name, PETSC_REAL, &e));
  e->r = value;
  PetscFunctionReturn(0);
}

PetscErrorCode ReportSetInt(Report r, const char name[], PetscInt value)
{
  ReportEntry *e;

  PetscFunctionBeginUser;
  PetscCall(ReportEntryGet(r, name, PETSC_INT, &e));
  e->i = value;
  PetscFunctionReturn(0);
}

PetscErrorCode ReportSetBool(Report r, const char name[], PetscBool value)
{
  ReportEntry *e;

  PetscFunctionBeginUser;
  PetscCall(ReportEntryGet(r, name, PETSC_BOOL, &e));
  e->i = value ? 1 : 0;
  PetscFunctionReturn(0);
}

PetscErrorCode ReportSetString(Report r, const char name[], const char value[])
{
  ReportEntry *e;

  PetscFunctionBeginUser;
  PetscCall(ReportEntryGet(r, name, PETSC_STRING, &e));
  PetscCall(PetscStrallocpy(value ? value : "", &e->s));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportViewReal(Report r, PetscViewer viewer, const char name[], const char format[], PetscReal value)
{
  PetscFunctionBeginUser;
  PetscCall(ReportSetReal(r, name, value));
  if (viewer) PetscCall(PetscViewerASCIIPrintf(viewer, format, (double) value));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportViewPercent(Report r, PetscViewer viewer, const char name[], const char format[], PetscReal fraction)
{
  PetscFunctionBeginUser;
  PetscCall(ReportSetReal(r, name, fraction));
  if (viewer) PetscCall(PetscViewerASCIIPrintf(viewer, format, (double) (100 * fraction)));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportViewInt(Report r, PetscViewer viewer, const char name[], const char format[], PetscInt value)
{
  PetscFunctionBeginUser;
  PetscCall(ReportSetInt(r, name, value));
  if (viewer) PetscCall(PetscViewerASCIIPrintf(viewer, format, value));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportViewString(Report r, PetscViewer viewer, const char name[], const char format[], const char value[])
{
  PetscFunctionBeginUser;
  PetscCall(ReportSetString(r, name, value));
  if (viewer) PetscCall(PetscViewerASCIIPrintf(viewer, format, value ? value : ""));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportGetSize(Report r, PetscInt *n)
{
  PetscFunctionBeginUser;
  *n = r->n;
  PetscFunctionReturn(0);
}

PetscErrorCode ReportGetEntry(Report r, PetscInt k, const char **name, PetscDataType *type, PetscReal *real, PetscInt *i, const char **s)
{
  PetscFunctionBeginUser;
  PetscCheck(k >= 0 && k < r->n, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "Report entry %" PetscInt_FMT " of %" PetscInt_FMT, k, r->n);
  if (name) *name = r->e[k].name;
  if (type) *type = r->e[k].type;
  if (real) *real = r->e[k].r;
  if (i) *i = r->e[k].i;
  if (s) *s = r->e[k].s;
  PetscFunctionReturn(0);
}

/* A JSON string: quotes, backslashes and control characters escaped. */
static PetscErrorCode PrintJSONString(MPI_Comm comm, const char *s)
{
  PetscFunctionBeginUser;
  PetscCall(PetscPrintf(comm, "\""));
  for (const unsigned char *c = (const unsigned char *) s; *c; c++) {
    if (*c == '"' || *c == '\\')
      PetscCall(PetscPrintf(comm, "\\%c", *c));
    else if (*c < 0x20)
      PetscCall(PetscPrintf(comm, "\\u%04x", (unsigned) *c));
    else
      PetscCall(PetscPrintf(comm, "%c", *c));
  }
  PetscCall(PetscPrintf(comm, "\""));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportPrintJSON(Report r)
{
  PetscFunctionBeginUser;
  PetscCall(PetscPrintf(r->comm, "{"));
  for (PetscInt k = 0; k < r->n; k++) {
    const ReportEntry *e = &r->e[k];
    PetscCall(PetscPrintf(r->comm, k ? ", \"%s\": " : "\"%s\": ", e->name));
    switch (e->type) {
    case PETSC_REAL:
      if (PetscIsInfOrNanReal(e->r) || PetscAbsReal(e->r) >= PETSC_INFINITY) /* PETSc's infinity is a finite number */
        PetscCall(PetscPrintf(r->comm, "null"));
      else
        PetscCall(PetscPrintf(r->comm, "%.17g", (double) e->r));
      break;
    case PETSC_INT:
      PetscCall(PetscPrintf(r->comm, "%" PetscInt_FMT, e->i));
      break;
    case PETSC_BOOL:
      PetscCall(PetscPrintf(r->comm, e->i ? "true" : "false"));
      break;
    default:
      PetscCall(PrintJSONString(r->comm, e->s));
    }
  }
  PetscCall(PetscPrintf(r->comm, "}\n"));
  PetscFunctionReturn(0);
}

PetscErrorCode ReportCPUTime(PetscLogDouble *seconds)
{
  struct rusage u;

  PetscFunctionBeginUser;
  PetscCheck(getrusage(RUSAGE_SELF, &u) == 0, PETSC_COMM_SELF, PETSC_ERR_SYS, "getrusage(RUSAGE_SELF) failed: the process's CPU time is unknown");
  *seconds = (PetscLogDouble) u.ru_utime.tv_sec + 1e-6 * (PetscLogDouble) u.ru_utime.tv_usec + (PetscLogDouble) u.ru_stime.tv_sec + 1e-6 * (PetscLogDouble) u.ru_stime.tv_usec;
  PetscFunctionReturn(0);
}

PetscErrorCode ReportPeakMemory(PetscLogDouble *bytes)
{
  struct rusage u;
  FILE         *f = fopen("/proc/self/status", "r");

  PetscFunctionBeginUser;
  *bytes = -1;
  if (f) {
    char   line[256];
    double kb;
    while (fgets(line, sizeof line, f))
      if (sscanf(line, "VmHWM: %lf kB", &kb) == 1) {
        *bytes = 1024 * kb;
        break;
      }
    fclose(f);
  }
  if (*bytes >= 0) PetscFunctionReturn(0);
  PetscCheck(getrusage(RUSAGE_SELF, &u) == 0, PETSC_COMM_SELF, PETSC_ERR_SYS, "getrusage(RUSAGE_SELF) failed: the process's peak memory is unknown");
  *bytes = 1024 * (PetscLogDouble) u.ru_maxrss; /* kB on Linux */
  PetscFunctionReturn(0);
}
