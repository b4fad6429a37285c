// A QTable whose rows the server patches cell by cell (see _live_table.py for why).
// The cell templates live in this component's own template: compiled once, one component
// type for the life of the page, so Vue patches a changed cell's text instead of
// re-creating every cell whenever anything on the page changes.
export default {
  template: `
    <q-table :rows="shown" :columns="columns" :row-key="rowKey" v-model:pagination="paging"
             :visible-columns="visible">
      <template v-for="name in badges" :key="name" v-slot:[cellSlot(name)]="props">
        <q-td :props="props">
          <q-badge v-if="props.value" color="negative" multi-line :label="props.value"
                   style="word-break: keep-all; text-align: center" />
        </q-td>
      </template>
      <template v-for="name in titled" :key="name" v-slot:[cellSlot(name)]="props">
        <q-td :props="props" :title="props.value"><template
          v-for="part in String(props.value).split(/(?<=[/._])/)">{{ part }}<wbr></template>
        </q-td>
      </template>
    </q-table>
  `,
  props: {
    rows: Array,
    columns: Array,
    rowKey: String,
    pagination: Object,
    visibleColumns: Array,
  },
  data() {
    return { shown: this.copy(this.rows), paging: { ...this.pagination },
             visible: this.visibleColumns };
  },
  computed: {
    badges() {
      return this.columns.filter((c) => c.cell === "badge").map((c) => c.name);
    },
    titled() {
      return this.columns.filter((c) => c.cell === "titled").map((c) => c.name);
    },
  },
  watch: {
    // The server re-sent the whole element (a column switch, a reconnect): start over.
    rows(rows) {
      this.shown = this.copy(rows);
    },
    visibleColumns(columns) {
      this.visible = columns;
    },
  },
  methods: {
    cellSlot(name) {
      return "body-cell-" + name;
    },
    copy(rows) {
      return (rows || []).map((row) => ({ ...row }));
    },
    setVisible(columns) {
      this.visible = columns;
    },
    // changes: {set: [partial rows, each with its key], remove: [keys]}.
    patch(changes) {
      const key = this.rowKey;
      if (changes.remove.length) {
        const gone = new Set(changes.remove);
        this.shown = this.shown.filter((row) => !gone.has(row[key]));
      }
      const index = new Map(this.shown.map((row) => [row[key], row]));
      for (const part of changes.set) {
        const row = index.get(part[key]);
        if (row) Object.assign(row, part);
        else this.shown.push({ ...part });
      }
    },
  },
};
